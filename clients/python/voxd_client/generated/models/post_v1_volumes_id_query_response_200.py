from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Self, TypeVar

from attrs import define as _attrs_define
from attrs import field as _attrs_field

if TYPE_CHECKING:
    from ..models.post_v1_volumes_id_query_response_200_points_item import (
        PostV1VolumesIdQueryResponse200PointsItem,
    )
    from ..models.post_v1_volumes_id_query_response_200_rays_item import (
        PostV1VolumesIdQueryResponse200RaysItem,
    )


T = TypeVar("T", bound="PostV1VolumesIdQueryResponse200")


@_attrs_define
class PostV1VolumesIdQueryResponse200:
    """
    Attributes:
        points (list[PostV1VolumesIdQueryResponse200PointsItem]):
        rays (list[PostV1VolumesIdQueryResponse200RaysItem]):
    """

    points: list[PostV1VolumesIdQueryResponse200PointsItem]
    rays: list[PostV1VolumesIdQueryResponse200RaysItem]
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        points = []
        for points_item_data in self.points:
            points_item = points_item_data.to_dict()
            points.append(points_item)

        rays = []
        for rays_item_data in self.rays:
            rays_item = rays_item_data.to_dict()
            rays.append(rays_item)

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "points": points,
                "rays": rays,
            }
        )

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        from ..models.post_v1_volumes_id_query_response_200_points_item import (
            PostV1VolumesIdQueryResponse200PointsItem,
        )
        from ..models.post_v1_volumes_id_query_response_200_rays_item import (
            PostV1VolumesIdQueryResponse200RaysItem,
        )

        d = dict(src_dict)
        points = []
        _points = d.pop("points")
        for points_item_data in _points:
            points_item = PostV1VolumesIdQueryResponse200PointsItem.from_dict(
                points_item_data
            )

            points.append(points_item)

        rays = []
        _rays = d.pop("rays")
        for rays_item_data in _rays:
            rays_item = PostV1VolumesIdQueryResponse200RaysItem.from_dict(
                rays_item_data
            )

            rays.append(rays_item)

        post_v1_volumes_id_query_response_200 = cls(
            points=points,
            rays=rays,
        )

        post_v1_volumes_id_query_response_200.additional_properties = d
        return post_v1_volumes_id_query_response_200

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
