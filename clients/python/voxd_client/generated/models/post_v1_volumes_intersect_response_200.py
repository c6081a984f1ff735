from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar

from attrs import define as _attrs_define
from attrs import field as _attrs_field

T = TypeVar("T", bound="PostV1VolumesIntersectResponse200")


@_attrs_define
class PostV1VolumesIntersectResponse200:
    """
    Attributes:
        a (str):
        b (str):
        voxels (int):
        volume (float):
    """

    a: str
    b: str
    voxels: int
    volume: float
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        a = self.a

        b = self.b

        voxels = self.voxels

        volume = self.volume

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "a": a,
                "b": b,
                "voxels": voxels,
                "volume": volume,
            }
        )

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        a = d.pop("a")

        b = d.pop("b")

        voxels = d.pop("voxels")

        volume = d.pop("volume")

        post_v1_volumes_intersect_response_200 = cls(
            a=a,
            b=b,
            voxels=voxels,
            volume=volume,
        )

        post_v1_volumes_intersect_response_200.additional_properties = d
        return post_v1_volumes_intersect_response_200

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
