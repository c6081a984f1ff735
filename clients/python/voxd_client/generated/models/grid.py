from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

T = TypeVar("T", bound="Grid")


@_attrs_define
class Grid:
    """
    Attributes:
        origin (list[float]):
        voxel_size (float):
        dims (list[int]):
    """

    origin: list[float]
    voxel_size: float
    dims: list[int]
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        origin = self.origin

        voxel_size = self.voxel_size

        dims = self.dims

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "origin": origin,
                "voxel_size": voxel_size,
                "dims": dims,
            }
        )

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        origin = cast(list[float], d.pop("origin"))

        voxel_size = d.pop("voxel_size")

        dims = cast(list[int], d.pop("dims"))

        grid = cls(
            origin=origin,
            voxel_size=voxel_size,
            dims=dims,
        )

        grid.additional_properties = d
        return grid

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
