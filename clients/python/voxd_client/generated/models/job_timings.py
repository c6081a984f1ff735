from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..types import UNSET, Unset

T = TypeVar("T", bound="JobTimings")


@_attrs_define
class JobTimings:
    """
    Attributes:
        queued_s (float | None | Unset):
        running_s (float | None | Unset):
    """

    queued_s: float | None | Unset = UNSET
    running_s: float | None | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        queued_s: float | None | Unset
        if isinstance(self.queued_s, Unset):
            queued_s = UNSET
        else:
            queued_s = self.queued_s

        running_s: float | None | Unset
        if isinstance(self.running_s, Unset):
            running_s = UNSET
        else:
            running_s = self.running_s

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update({})
        if queued_s is not UNSET:
            field_dict["queued_s"] = queued_s
        if running_s is not UNSET:
            field_dict["running_s"] = running_s

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)

        def _parse_queued_s(data: object) -> float | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            return cast(float | None | Unset, data)

        queued_s = _parse_queued_s(d.pop("queued_s", UNSET))

        def _parse_running_s(data: object) -> float | None | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            return cast(float | None | Unset, data)

        running_s = _parse_running_s(d.pop("running_s", UNSET))

        job_timings = cls(
            queued_s=queued_s,
            running_s=running_s,
        )

        job_timings.additional_properties = d
        return job_timings

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
