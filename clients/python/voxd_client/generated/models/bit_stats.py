from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..types import UNSET, Unset

T = TypeVar("T", bound="BitStats")


@_attrs_define
class BitStats:
    """
    Attributes:
        solid_voxels (int):
        volume (float):
        surface_voxels (int):
        components_6 (int):
        components_26 (int):
        bounds_index (list[list[int]] | None | Unset):
        bounds_world (list[list[float]] | None | Unset):
        centre_of_mass (list[float] | None | Unset):
        inertia (list[list[float]] | None | Unset):
    """

    solid_voxels: int
    volume: float
    surface_voxels: int
    components_6: int
    components_26: int
    bounds_index: list[list[int]] | None | Unset = UNSET
    bounds_world: list[list[float]] | None | Unset = UNSET
    centre_of_mass: list[float] | None | Unset = UNSET
    inertia: list[list[float]] | None | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        solid_voxels = self.solid_voxels

        volume = self.volume

        surface_voxels = self.surface_voxels

        components_6 = self.components_6

        components_26 = self.components_26

        bounds_index: list[list[int]] | None | Unset
        if isinstance(self.bounds_index, Unset):
            bounds_index = UNSET
        elif isinstance(self.bounds_index, list):
            bounds_index = []
            for bounds_index_type_0_item_data in self.bounds_index:
                bounds_index_type_0_item = bounds_index_type_0_item_data

                bounds_index.append(bounds_index_type_0_item)

        else:
            bounds_index = self.bounds_index

        bounds_world: list[list[float]] | None | Unset
        if isinstance(self.bounds_world, Unset):
            bounds_world = UNSET
        elif isinstance(self.bounds_world, list):
            bounds_world = []
            for bounds_world_type_0_item_data in self.bounds_world:
                bounds_world_type_0_item = bounds_world_type_0_item_data

                bounds_world.append(bounds_world_type_0_item)

        else:
            bounds_world = self.bounds_world

        centre_of_mass: list[float] | None | Unset
        if isinstance(self.centre_of_mass, Unset):
            centre_of_mass = UNSET
        elif isinstance(self.centre_of_mass, list):
            centre_of_mass = self.centre_of_mass

        else:
            centre_of_mass = self.centre_of_mass

        inertia: list[list[float]] | None | Unset
        if isinstance(self.inertia, Unset):
            inertia = UNSET
        elif isinstance(self.inertia, list):
            inertia = []
            for inertia_type_0_item_data in self.inertia:
                inertia_type_0_item = inertia_type_0_item_data

                inertia.append(inertia_type_0_item)

        else:
            inertia = self.inertia

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "solid_voxels": solid_voxels,
                "volume": volume,
                "surface_voxels": surface_voxels,
                "components_6": components_6,
                "components_26": components_26,
            }
        )
        if bounds_index is not UNSET:
            field_dict["bounds_index"] = bounds_index
        if bounds_world is not UNSET:
            field_dict["bounds_world"] = bounds_world
        if centre_of_mass is not UNSET:
            field_dict["centre_of_mass"] = centre_of_mass
        if inertia is not UNSET:
            field_dict["inertia"] = inertia

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        solid_voxels = d.pop("solid_voxels")

        volume = d.pop("volume")

        surface_voxels = d.pop("surface_voxels")

        components_6 = d.pop("components_6")

        components_26 = d.pop("components_26")

        def _parse_bounds_index(data: object) -> list[list[int]] | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            try:
                if not isinstance(data, list):
                    raise TypeError()
                bounds_index_type_0 = []
                _bounds_index_type_0 = data
                for bounds_index_type_0_item_data in _bounds_index_type_0:
                    bounds_index_type_0_item = cast(
                        list[int], bounds_index_type_0_item_data
                    )

                    bounds_index_type_0.append(bounds_index_type_0_item)

                return bounds_index_type_0
            except (TypeError, ValueError, AttributeError, KeyError):
                pass
            return cast(list[list[int]] | None | Unset, data)

        bounds_index = _parse_bounds_index(d.pop("bounds_index", UNSET))

        def _parse_bounds_world(data: object) -> list[list[float]] | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            try:
                if not isinstance(data, list):
                    raise TypeError()
                bounds_world_type_0 = []
                _bounds_world_type_0 = data
                for bounds_world_type_0_item_data in _bounds_world_type_0:
                    bounds_world_type_0_item = cast(
                        list[float], bounds_world_type_0_item_data
                    )

                    bounds_world_type_0.append(bounds_world_type_0_item)

                return bounds_world_type_0
            except (TypeError, ValueError, AttributeError, KeyError):
                pass
            return cast(list[list[float]] | None | Unset, data)

        bounds_world = _parse_bounds_world(d.pop("bounds_world", UNSET))

        def _parse_centre_of_mass(data: object) -> list[float] | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            try:
                if not isinstance(data, list):
                    raise TypeError()
                centre_of_mass_type_0 = cast(list[float], data)

                return centre_of_mass_type_0
            except (TypeError, ValueError, AttributeError, KeyError):
                pass
            return cast(list[float] | None | Unset, data)

        centre_of_mass = _parse_centre_of_mass(d.pop("centre_of_mass", UNSET))

        def _parse_inertia(data: object) -> list[list[float]] | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            try:
                if not isinstance(data, list):
                    raise TypeError()
                inertia_type_0 = []
                _inertia_type_0 = data
                for inertia_type_0_item_data in _inertia_type_0:
                    inertia_type_0_item = cast(list[float], inertia_type_0_item_data)

                    inertia_type_0.append(inertia_type_0_item)

                return inertia_type_0
            except (TypeError, ValueError, AttributeError, KeyError):
                pass
            return cast(list[list[float]] | None | Unset, data)

        inertia = _parse_inertia(d.pop("inertia", UNSET))

        bit_stats = cls(
            solid_voxels=solid_voxels,
            volume=volume,
            surface_voxels=surface_voxels,
            components_6=components_6,
            components_26=components_26,
            bounds_index=bounds_index,
            bounds_world=bounds_world,
            centre_of_mass=centre_of_mass,
            inertia=inertia,
        )

        bit_stats.additional_properties = d
        return bit_stats

    @property
    def additional_keys(self) -> list[str]:
        return list(self.additional_properties.keys())

    def __getitem__(self, key: str) -> Any:
        return self.additional_properties[key]

    def __setitem__(self, key: str, value: Any) -> None:
        self.additional_properties[key] = value

    def __delitem__(self, key: str) -> None:
        del self.additional_properties[key]

    def __contains__(self, key: str) -> bool:
        return key in self.additional_properties
