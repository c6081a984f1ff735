from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..types import UNSET, Unset

T = TypeVar("T", bound="VolumeDiagnosticsType0")


@_attrs_define
class VolumeDiagnosticsType0:
    """
    Attributes:
        triangles (int | Unset):
        vertices (int | Unset):
        degenerate_triangles (int | Unset):
        boundary_edges (int | Unset):
        non_manifold_edges (int | Unset):
        watertight (bool | Unset):
        unoriented_edges (int | Unset): edges their triangles do not use as often in one direction as in the other
            (boundary edges, edges between triangles of opposite orientation); 0 on a closed, consistently oriented mesh;
            absent from volumes made before it was counted
        bbox_min (list[float] | Unset):
        bbox_max (list[float] | Unset):
        dropped_triangles (int | Unset): degenerate triangles (a repeated vertex or position) dropped at load as copies
            of a segment or point kept; not counted in triangles; absent when none
    """

    triangles: int | Unset = UNSET
    vertices: int | Unset = UNSET
    degenerate_triangles: int | Unset = UNSET
    boundary_edges: int | Unset = UNSET
    non_manifold_edges: int | Unset = UNSET
    watertight: bool | Unset = UNSET
    unoriented_edges: int | Unset = UNSET
    bbox_min: list[float] | Unset = UNSET
    bbox_max: list[float] | Unset = UNSET
    dropped_triangles: int | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        triangles = self.triangles

        vertices = self.vertices

        degenerate_triangles = self.degenerate_triangles

        boundary_edges = self.boundary_edges

        non_manifold_edges = self.non_manifold_edges

        watertight = self.watertight

        unoriented_edges = self.unoriented_edges

        bbox_min: list[float] | Unset = UNSET
        if not isinstance(self.bbox_min, Unset):
            bbox_min = self.bbox_min

        bbox_max: list[float] | Unset = UNSET
        if not isinstance(self.bbox_max, Unset):
            bbox_max = self.bbox_max

        dropped_triangles = self.dropped_triangles

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update({})
        if triangles is not UNSET:
            field_dict["triangles"] = triangles
        if vertices is not UNSET:
            field_dict["vertices"] = vertices
        if degenerate_triangles is not UNSET:
            field_dict["degenerate_triangles"] = degenerate_triangles
        if boundary_edges is not UNSET:
            field_dict["boundary_edges"] = boundary_edges
        if non_manifold_edges is not UNSET:
            field_dict["non_manifold_edges"] = non_manifold_edges
        if watertight is not UNSET:
            field_dict["watertight"] = watertight
        if unoriented_edges is not UNSET:
            field_dict["unoriented_edges"] = unoriented_edges
        if bbox_min is not UNSET:
            field_dict["bbox_min"] = bbox_min
        if bbox_max is not UNSET:
            field_dict["bbox_max"] = bbox_max
        if dropped_triangles is not UNSET:
            field_dict["dropped_triangles"] = dropped_triangles

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        triangles = d.pop("triangles", UNSET)

        vertices = d.pop("vertices", UNSET)

        degenerate_triangles = d.pop("degenerate_triangles", UNSET)

        boundary_edges = d.pop("boundary_edges", UNSET)

        non_manifold_edges = d.pop("non_manifold_edges", UNSET)

        watertight = d.pop("watertight", UNSET)

        unoriented_edges = d.pop("unoriented_edges", UNSET)

        bbox_min = cast(list[float], d.pop("bbox_min", UNSET))

        bbox_max = cast(list[float], d.pop("bbox_max", UNSET))

        dropped_triangles = d.pop("dropped_triangles", UNSET)

        volume_diagnostics_type_0 = cls(
            triangles=triangles,
            vertices=vertices,
            degenerate_triangles=degenerate_triangles,
            boundary_edges=boundary_edges,
            non_manifold_edges=non_manifold_edges,
            watertight=watertight,
            unoriented_edges=unoriented_edges,
            bbox_min=bbox_min,
            bbox_max=bbox_max,
            dropped_triangles=dropped_triangles,
        )

        volume_diagnostics_type_0.additional_properties = d
        return volume_diagnostics_type_0

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
