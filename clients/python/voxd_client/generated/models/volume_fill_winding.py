from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..types import UNSET, Unset

T = TypeVar("T", bound="VolumeFillWinding")


@_attrs_define
class VolumeFillWinding:
    """for the winding fill, how its voxels were decided

    Attributes:
        cap_triangles (int | Unset): triangles added to close the boundary cycles
        exact_voxels (int | Unset): decided by the exact signed crossing count alone (the caps' winding number proven
            below 0.45)
        cap_block_voxels (int | Unset): decided a block at a time by the crossing count against an integer: the caps'
            winding number over the block is bounded away from every half-integer
        mesh_block_voxels (int | Unset): decided a block at a time by the mesh's winding number, bounded away from ±½
            over the block
        cap_evaluated_voxels (int | Unset): decided one by one by the crossing count minus the caps' winding number
        mesh_evaluated_voxels (int | Unset): decided by the mesh's own winding number (voxels on a cap's plane)
        near_evaluated_voxels (int | Unset): decided one by one by the crossing count minus the caps' winding number,
            taken as the exact sum over the cap triangles near the voxel's small block plus an interval for the far ones
    """

    cap_triangles: int | Unset = UNSET
    exact_voxels: int | Unset = UNSET
    cap_block_voxels: int | Unset = UNSET
    mesh_block_voxels: int | Unset = UNSET
    cap_evaluated_voxels: int | Unset = UNSET
    mesh_evaluated_voxels: int | Unset = UNSET
    near_evaluated_voxels: int | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        cap_triangles = self.cap_triangles

        exact_voxels = self.exact_voxels

        cap_block_voxels = self.cap_block_voxels

        mesh_block_voxels = self.mesh_block_voxels

        cap_evaluated_voxels = self.cap_evaluated_voxels

        mesh_evaluated_voxels = self.mesh_evaluated_voxels

        near_evaluated_voxels = self.near_evaluated_voxels

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update({})
        if cap_triangles is not UNSET:
            field_dict["cap_triangles"] = cap_triangles
        if exact_voxels is not UNSET:
            field_dict["exact_voxels"] = exact_voxels
        if cap_block_voxels is not UNSET:
            field_dict["cap_block_voxels"] = cap_block_voxels
        if mesh_block_voxels is not UNSET:
            field_dict["mesh_block_voxels"] = mesh_block_voxels
        if cap_evaluated_voxels is not UNSET:
            field_dict["cap_evaluated_voxels"] = cap_evaluated_voxels
        if mesh_evaluated_voxels is not UNSET:
            field_dict["mesh_evaluated_voxels"] = mesh_evaluated_voxels
        if near_evaluated_voxels is not UNSET:
            field_dict["near_evaluated_voxels"] = near_evaluated_voxels

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        cap_triangles = d.pop("cap_triangles", UNSET)

        exact_voxels = d.pop("exact_voxels", UNSET)

        cap_block_voxels = d.pop("cap_block_voxels", UNSET)

        mesh_block_voxels = d.pop("mesh_block_voxels", UNSET)

        cap_evaluated_voxels = d.pop("cap_evaluated_voxels", UNSET)

        mesh_evaluated_voxels = d.pop("mesh_evaluated_voxels", UNSET)

        near_evaluated_voxels = d.pop("near_evaluated_voxels", UNSET)

        volume_fill_winding = cls(
            cap_triangles=cap_triangles,
            exact_voxels=exact_voxels,
            cap_block_voxels=cap_block_voxels,
            mesh_block_voxels=mesh_block_voxels,
            cap_evaluated_voxels=cap_evaluated_voxels,
            mesh_evaluated_voxels=mesh_evaluated_voxels,
            near_evaluated_voxels=near_evaluated_voxels,
        )

        volume_fill_winding.additional_properties = d
        return volume_fill_winding

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
