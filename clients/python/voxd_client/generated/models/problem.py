from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..types import UNSET, Unset

T = TypeVar("T", bound="Problem")


@_attrs_define
class Problem:
    """`type` is one of: https://voxd.dev/problems/invalid-mesh (422), unsupported-media-type (415),
    external-resource (422), too-many-triangles (422), body-too-large (413), grid-too-large (422),
    invalid-parameter (400), queue-full (429), queue-unavailable (503), not-found (404),
    not-cancelable (409), storage-full (507), storage-unavailable (503),
    engine-failure (500), shutting-down (503),
    misaligned-grids (422), wrong-volume-kind (422), empty-intersection (422), too-much-memory (422),
    timeout (408),
    busy (503), method-not-allowed (405), precondition-failed (412), uri-too-long (414),
    headers-too-large (431),
    expectation-failed (417),
    range-not-satisfiable (416),
    unauthorized (401), forbidden (403), rate-limited (429), too-many-jobs (429),
    source-not-kept (409), missing-attributes (422), internal (500).

        Attributes:
            type_ (str):
            title (str):
            status (int):
            detail (str):
            instance (str | Unset):
            request_id (str | Unset):
    """

    type_: str
    title: str
    status: int
    detail: str
    instance: str | Unset = UNSET
    request_id: str | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        type_ = self.type_

        title = self.title

        status = self.status

        detail = self.detail

        instance = self.instance

        request_id = self.request_id

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "type": type_,
                "title": title,
                "status": status,
                "detail": detail,
            }
        )
        if instance is not UNSET:
            field_dict["instance"] = instance
        if request_id is not UNSET:
            field_dict["request_id"] = request_id

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        type_ = d.pop("type")

        title = d.pop("title")

        status = d.pop("status")

        detail = d.pop("detail")

        instance = d.pop("instance", UNSET)

        request_id = d.pop("request_id", UNSET)

        problem = cls(
            type_=type_,
            title=title,
            status=status,
            detail=detail,
            instance=instance,
            request_id=request_id,
        )

        problem.additional_properties = d
        return problem

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
