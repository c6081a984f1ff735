from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar

from attrs import define as _attrs_define

T = TypeVar("T", bound="PostV1VolumesIntersectBody")


@_attrs_define
class PostV1VolumesIntersectBody:
    """
    Attributes:
        a (str):
        b (str):
    """

    a: str
    b: str

    def to_dict(self) -> dict[str, Any]:
        a = self.a

        b = self.b

        field_dict: dict[str, Any] = {}

        field_dict.update(
            {
                "a": a,
                "b": b,
            }
        )

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        a = d.pop("a")

        b = d.pop("b")

        post_v1_volumes_intersect_body = cls(
            a=a,
            b=b,
        )

        return post_v1_volumes_intersect_body
