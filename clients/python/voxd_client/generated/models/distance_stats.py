from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..types import UNSET, Unset

T = TypeVar("T", bound="DistanceStats")


@_attrs_define
class DistanceStats:
    """statistics of a distance volume; B is its background (the band's width)

    Attributes:
        active_voxels (int): voxels with |v| < B (in the band)
        inside_voxels (int): voxels whose sign bit is set
        enclosed_volume (float): inside_voxels * voxel_size^3 (the inside voxels' cubes)
        bricks (int):
        tiles (int):
        band_voxels (float | None | Unset): B / voxel_size (null: B is +inf)
        background (float | None | Unset):
        min_ (float | None | Unset):
        max_ (float | None | Unset):
    """

    active_voxels: int
    inside_voxels: int
    enclosed_volume: float
    bricks: int
    tiles: int
    band_voxels: float | None | Unset = UNSET
    background: float | None | Unset = UNSET
    min_: float | None | Unset = UNSET
    max_: float | None | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        active_voxels = self.active_voxels

        inside_voxels = self.inside_voxels

        enclosed_volume = self.enclosed_volume

        bricks = self.bricks

        tiles = self.tiles

        band_voxels: float | None | Unset
        if isinstance(self.band_voxels, Unset):
            band_voxels = UNSET
        else:
            band_voxels = self.band_voxels

        background: float | None | Unset
        if isinstance(self.background, Unset):
            background = UNSET
        else:
            background = self.background

        min_: float | None | Unset
        if isinstance(self.min_, Unset):
            min_ = UNSET
        else:
            min_ = self.min_

        max_: float | None | Unset
        if isinstance(self.max_, Unset):
            max_ = UNSET
        else:
            max_ = self.max_

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "active_voxels": active_voxels,
                "inside_voxels": inside_voxels,
                "enclosed_volume": enclosed_volume,
                "bricks": bricks,
                "tiles": tiles,
            }
        )
        if band_voxels is not UNSET:
            field_dict["band_voxels"] = band_voxels
        if background is not UNSET:
            field_dict["background"] = background
        if min_ is not UNSET:
            field_dict["min"] = min_
        if max_ is not UNSET:
            field_dict["max"] = max_

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        active_voxels = d.pop("active_voxels")

        inside_voxels = d.pop("inside_voxels")

        enclosed_volume = d.pop("enclosed_volume")

        bricks = d.pop("bricks")

        tiles = d.pop("tiles")

        def _parse_band_voxels(data: object) -> float | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            return cast(float | None | Unset, data)

        band_voxels = _parse_band_voxels(d.pop("band_voxels", UNSET))

        def _parse_background(data: object) -> float | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            return cast(float | None | Unset, data)

        background = _parse_background(d.pop("background", UNSET))

        def _parse_min_(data: object) -> float | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            return cast(float | None | Unset, data)

        min_ = _parse_min_(d.pop("min", UNSET))

        def _parse_max_(data: object) -> float | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            return cast(float | None | Unset, data)

        max_ = _parse_max_(d.pop("max", UNSET))

        distance_stats = cls(
            active_voxels=active_voxels,
            inside_voxels=inside_voxels,
            enclosed_volume=enclosed_volume,
            bricks=bricks,
            tiles=tiles,
            band_voxels=band_voxels,
            background=background,
            min_=min_,
            max_=max_,
        )

        distance_stats.additional_properties = d
        return distance_stats

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
