from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar

from attrs import define as _attrs_define
from attrs import field as _attrs_field

T = TypeVar("T", bound="PostV1VolumesIdQueryResponse200PointsItem")


@_attrs_define
class PostV1VolumesIdQueryResponse200PointsItem:
    """
    Attributes:
        inside (bool):
        value (int):
    """

    inside: bool
    value: int
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        inside = self.inside

        value = self.value

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "inside": inside,
                "value": value,
            }
        )

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        inside = d.pop("inside")

        value = d.pop("value")

        post_v1_volumes_id_query_response_200_points_item = cls(
            inside=inside,
            value=value,
        )

        post_v1_volumes_id_query_response_200_points_item.additional_properties = d
        return post_v1_volumes_id_query_response_200_points_item

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
