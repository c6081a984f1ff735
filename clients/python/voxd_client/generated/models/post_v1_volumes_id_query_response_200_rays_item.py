from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..types import UNSET, Unset

T = TypeVar("T", bound="PostV1VolumesIdQueryResponse200RaysItem")


@_attrs_define
class PostV1VolumesIdQueryResponse200RaysItem:
    """
    Attributes:
        solid_voxels (int):
        thickness (float):
        entry (float | None | Unset):
        exit_ (float | None | Unset):
    """

    solid_voxels: int
    thickness: float
    entry: float | None | Unset = UNSET
    exit_: float | None | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        solid_voxels = self.solid_voxels

        thickness = self.thickness

        entry: float | None | Unset
        if isinstance(self.entry, Unset):
            entry = UNSET
        else:
            entry = self.entry

        exit_: float | None | Unset
        if isinstance(self.exit_, Unset):
            exit_ = UNSET
        else:
            exit_ = self.exit_

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "solid_voxels": solid_voxels,
                "thickness": thickness,
            }
        )
        if entry is not UNSET:
            field_dict["entry"] = entry
        if exit_ is not UNSET:
            field_dict["exit"] = exit_

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        solid_voxels = d.pop("solid_voxels")

        thickness = d.pop("thickness")

        def _parse_entry(data: object) -> float | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            return cast(float | None | Unset, data)

        entry = _parse_entry(d.pop("entry", UNSET))

        def _parse_exit_(data: object) -> float | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            return cast(float | None | Unset, data)

        exit_ = _parse_exit_(d.pop("exit", UNSET))

        post_v1_volumes_id_query_response_200_rays_item = cls(
            solid_voxels=solid_voxels,
            thickness=thickness,
            entry=entry,
            exit_=exit_,
        )

        post_v1_volumes_id_query_response_200_rays_item.additional_properties = d
        return post_v1_volumes_id_query_response_200_rays_item

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
