from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..models.volume_source_compression import VolumeSourceCompression
from ..types import UNSET, Unset

T = TypeVar("T", bound="VolumeSource")


@_attrs_define
class VolumeSource:
    """
    Attributes:
        format_ (str): the mesh's format (obj, glb, gltf, stl, ply; of the mesh inside a gzip'd upload); for a derived
            volume, how it was made
        sha256 (str): sha256 of the uploaded bytes (of a derived volume: of its provenance)
        triangles (int):
        compression (VolumeSourceCompression | Unset): set when the upload was gzip'd, or a zip holding the mesh and its
            files
        kept (bool | Unset): true when the mesh is kept in the store (under sha256, shared by the volumes made from the
            same upload, counted in the quota, removed with the last of them) for GET /v1/volumes/{id}/hermite and
            algorithm=dual-contouring; absent otherwise
    """

    format_: str
    sha256: str
    triangles: int
    compression: VolumeSourceCompression | Unset = UNSET
    kept: bool | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        format_ = self.format_

        sha256 = self.sha256

        triangles = self.triangles

        compression: str | Unset = UNSET
        if not isinstance(self.compression, Unset):
            compression = self.compression.value

        kept = self.kept

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "format": format_,
                "sha256": sha256,
                "triangles": triangles,
            }
        )
        if compression is not UNSET:
            field_dict["compression"] = compression
        if kept is not UNSET:
            field_dict["kept"] = kept

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        format_ = d.pop("format")

        sha256 = d.pop("sha256")

        triangles = d.pop("triangles")

        _compression = d.pop("compression", UNSET)
        compression: VolumeSourceCompression | Unset
        if isinstance(_compression, Unset):
            compression = UNSET
        else:
            compression = VolumeSourceCompression(_compression)

        kept = d.pop("kept", UNSET)

        volume_source = cls(
            format_=format_,
            sha256=sha256,
            triangles=triangles,
            compression=compression,
            kept=kept,
        )

        volume_source.additional_properties = d
        return volume_source

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
