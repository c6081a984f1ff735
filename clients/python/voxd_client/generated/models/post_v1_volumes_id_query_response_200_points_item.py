from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..types import UNSET, Unset

T = TypeVar("T", bound="PostV1VolumesIdQueryResponse200PointsItem")


@_attrs_define
class PostV1VolumesIdQueryResponse200PointsItem:
    """
    Attributes:
        inside (bool):
        value (float): the voxel's value (0/1 for bits; the stored f32 for distance volumes)
        distance (float | Unset): distance volumes: the trilinear interpolation of the voxel-centre samples (outside the
            grid: the background); absent where a sample is infinite
        gradient (list[float] | Unset): distance volumes: the interpolant's gradient, per world unit
    """

    inside: bool
    value: float
    distance: float | Unset = UNSET
    gradient: list[float] | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        inside = self.inside

        value = self.value

        distance = self.distance

        gradient: list[float] | Unset = UNSET
        if not isinstance(self.gradient, Unset):
            gradient = self.gradient

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "inside": inside,
                "value": value,
            }
        )
        if distance is not UNSET:
            field_dict["distance"] = distance
        if gradient is not UNSET:
            field_dict["gradient"] = gradient

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        inside = d.pop("inside")

        value = d.pop("value")

        distance = d.pop("distance", UNSET)

        gradient = cast(list[float], d.pop("gradient", UNSET))

        post_v1_volumes_id_query_response_200_points_item = cls(
            inside=inside,
            value=value,
            distance=distance,
            gradient=gradient,
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
