from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Self, TypeVar

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..models.volume_fill_requested import VolumeFillRequested
from ..models.volume_fill_used import VolumeFillUsed
from ..types import UNSET, Unset

if TYPE_CHECKING:
    from ..models.volume_fill_winding import VolumeFillWinding


T = TypeVar("T", bound="VolumeFill")


@_attrs_define
class VolumeFill:
    """how the solid was filled (absent for volumes derived by CSG or morphology)

    Attributes:
        requested (VolumeFillRequested):
        used (VolumeFillUsed): the fill applied (auto resolved)
        odd_parity_columns (int): grid columns the mesh covers an odd number of times (holes along z); for density,
            columns of the finer grid
        warning (str | Unset): set when parity was used on a mesh that is not watertight
        reason (str | Unset): for auto: why it resolved to the fill used (the mesh watertight or not)
        winding (VolumeFillWinding | Unset): for the winding fill, how its voxels were decided
    """

    requested: VolumeFillRequested
    used: VolumeFillUsed
    odd_parity_columns: int
    warning: str | Unset = UNSET
    reason: str | Unset = UNSET
    winding: VolumeFillWinding | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        requested = self.requested.value

        used = self.used.value

        odd_parity_columns = self.odd_parity_columns

        warning = self.warning

        reason = self.reason

        winding: dict[str, Any] | Unset = UNSET
        if not isinstance(self.winding, Unset):
            winding = self.winding.to_dict()

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "requested": requested,
                "used": used,
                "odd_parity_columns": odd_parity_columns,
            }
        )
        if warning is not UNSET:
            field_dict["warning"] = warning
        if reason is not UNSET:
            field_dict["reason"] = reason
        if winding is not UNSET:
            field_dict["winding"] = winding

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        from ..models.volume_fill_winding import VolumeFillWinding

        d = dict(src_dict)
        requested = VolumeFillRequested(d.pop("requested"))

        used = VolumeFillUsed(d.pop("used"))

        odd_parity_columns = d.pop("odd_parity_columns")

        warning = d.pop("warning", UNSET)

        reason = d.pop("reason", UNSET)

        _winding = d.pop("winding", UNSET)
        winding: VolumeFillWinding | Unset
        if isinstance(_winding, Unset):
            winding = UNSET
        else:
            winding = VolumeFillWinding.from_dict(_winding)

        volume_fill = cls(
            requested=requested,
            used=used,
            odd_parity_columns=odd_parity_columns,
            warning=warning,
            reason=reason,
            winding=winding,
        )

        volume_fill.additional_properties = d
        return volume_fill

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
