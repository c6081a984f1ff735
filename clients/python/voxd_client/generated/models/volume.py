from __future__ import annotations

import datetime
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..models.volume_kind import VolumeKind
from ..types import UNSET, Unset

if TYPE_CHECKING:
    from ..models.grid import Grid
    from ..models.volume_attributes import VolumeAttributes
    from ..models.volume_diagnostics_type_0 import VolumeDiagnosticsType0
    from ..models.volume_distance import VolumeDistance
    from ..models.volume_fill import VolumeFill
    from ..models.volume_source import VolumeSource


T = TypeVar("T", bound="Volume")


@_attrs_define
class Volume:
    """
    Attributes:
        id (str):
        kind (VolumeKind): channels: bit volumes with attribute channels (color=true, material=true)
        method (str):
        grid (Grid):
        solid_voxels (int):
        volume (float):
        source (VolumeSource):
        engine (str):
        created (datetime.datetime):
        bytes_ (int):
        sha256 (str):
        name (None | str | Unset):
        diagnostics (None | Unset | VolumeDiagnosticsType0):
        fill (VolumeFill | Unset): how the solid was filled (absent for volumes derived by CSG or morphology)
        provenance (Any | Unset): how a derived volume was made: a CSG expression or {morphology: {...}}
        attributes (VolumeAttributes | Unset): volumes of kind channels: their channels and the material table
        distance (VolumeDistance | Unset): distance volumes (kind sparse-distance) and method=distance: how the
            distances were kept
        owner (str | Unset): with API keys: the tenant that owns the volume; another tenant's volume is 404
            (docs/security.md, Tenants)
    """

    id: str
    kind: VolumeKind
    method: str
    grid: Grid
    solid_voxels: int
    volume: float
    source: VolumeSource
    engine: str
    created: datetime.datetime
    bytes_: int
    sha256: str
    name: None | str | Unset = UNSET
    diagnostics: None | Unset | VolumeDiagnosticsType0 = UNSET
    fill: VolumeFill | Unset = UNSET
    provenance: Any | Unset = UNSET
    attributes: VolumeAttributes | Unset = UNSET
    distance: VolumeDistance | Unset = UNSET
    owner: str | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        from ..models.volume_diagnostics_type_0 import VolumeDiagnosticsType0

        id = self.id

        kind = self.kind.value

        method = self.method

        grid = self.grid.to_dict()

        solid_voxels = self.solid_voxels

        volume = self.volume

        source = self.source.to_dict()

        engine = self.engine

        created = self.created.isoformat()

        bytes_ = self.bytes_

        sha256 = self.sha256

        name: None | str | Unset
        if isinstance(self.name, Unset):
            name = UNSET
        else:
            name = self.name

        diagnostics: dict[str, Any] | None | Unset
        if isinstance(self.diagnostics, Unset):
            diagnostics = UNSET
        elif isinstance(self.diagnostics, VolumeDiagnosticsType0):
            diagnostics = self.diagnostics.to_dict()
        else:
            diagnostics = self.diagnostics

        fill: dict[str, Any] | Unset = UNSET
        if not isinstance(self.fill, Unset):
            fill = self.fill.to_dict()

        provenance = self.provenance

        attributes: dict[str, Any] | Unset = UNSET
        if not isinstance(self.attributes, Unset):
            attributes = self.attributes.to_dict()

        distance: dict[str, Any] | Unset = UNSET
        if not isinstance(self.distance, Unset):
            distance = self.distance.to_dict()

        owner = self.owner

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "id": id,
                "kind": kind,
                "method": method,
                "grid": grid,
                "solid_voxels": solid_voxels,
                "volume": volume,
                "source": source,
                "engine": engine,
                "created": created,
                "bytes": bytes_,
                "sha256": sha256,
            }
        )
        if name is not UNSET:
            field_dict["name"] = name
        if diagnostics is not UNSET:
            field_dict["diagnostics"] = diagnostics
        if fill is not UNSET:
            field_dict["fill"] = fill
        if provenance is not UNSET:
            field_dict["provenance"] = provenance
        if attributes is not UNSET:
            field_dict["attributes"] = attributes
        if distance is not UNSET:
            field_dict["distance"] = distance
        if owner is not UNSET:
            field_dict["owner"] = owner

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        from ..models.grid import Grid
        from ..models.volume_attributes import VolumeAttributes
        from ..models.volume_diagnostics_type_0 import VolumeDiagnosticsType0
        from ..models.volume_distance import VolumeDistance
        from ..models.volume_fill import VolumeFill
        from ..models.volume_source import VolumeSource

        d = dict(src_dict)
        id = d.pop("id")

        kind = VolumeKind(d.pop("kind"))

        method = d.pop("method")

        grid = Grid.from_dict(d.pop("grid"))

        solid_voxels = d.pop("solid_voxels")

        volume = d.pop("volume")

        source = VolumeSource.from_dict(d.pop("source"))

        engine = d.pop("engine")

        created = datetime.datetime.fromisoformat(d.pop("created"))

        bytes_ = d.pop("bytes")

        sha256 = d.pop("sha256")

        def _parse_name(data: object) -> None | str | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            return cast(None | str | Unset, data)

        name = _parse_name(d.pop("name", UNSET))

        def _parse_diagnostics(data: object) -> None | Unset | VolumeDiagnosticsType0:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            try:
                if not isinstance(data, dict):
                    raise TypeError()
                diagnostics_type_0 = VolumeDiagnosticsType0.from_dict(data)

                return diagnostics_type_0
            except (TypeError, ValueError, AttributeError, KeyError):
                pass
            return cast(None | Unset | VolumeDiagnosticsType0, data)

        diagnostics = _parse_diagnostics(d.pop("diagnostics", UNSET))

        _fill = d.pop("fill", UNSET)
        fill: VolumeFill | Unset
        if isinstance(_fill, Unset):
            fill = UNSET
        else:
            fill = VolumeFill.from_dict(_fill)

        provenance = d.pop("provenance", UNSET)

        _attributes = d.pop("attributes", UNSET)
        attributes: VolumeAttributes | Unset
        if isinstance(_attributes, Unset):
            attributes = UNSET
        else:
            attributes = VolumeAttributes.from_dict(_attributes)

        _distance = d.pop("distance", UNSET)
        distance: VolumeDistance | Unset
        if isinstance(_distance, Unset):
            distance = UNSET
        else:
            distance = VolumeDistance.from_dict(_distance)

        owner = d.pop("owner", UNSET)

        volume = cls(
            id=id,
            kind=kind,
            method=method,
            grid=grid,
            solid_voxels=solid_voxels,
            volume=volume,
            source=source,
            engine=engine,
            created=created,
            bytes_=bytes_,
            sha256=sha256,
            name=name,
            diagnostics=diagnostics,
            fill=fill,
            provenance=provenance,
            attributes=attributes,
            distance=distance,
            owner=owner,
        )

        volume.additional_properties = d
        return volume

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
