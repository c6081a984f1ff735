from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..models.volume_distance_background_type_1 import VolumeDistanceBackgroundType1
from ..models.volume_distance_band_type_1 import VolumeDistanceBandType1
from ..types import UNSET, Unset

T = TypeVar("T", bound="VolumeDistance")


@_attrs_define
class VolumeDistance:
    """distance volumes (kind sparse-distance) and method=distance: how the distances were kept

    Attributes:
        band (int | Unset | VolumeDistanceBandType1): the band's half width in voxels, or "all"
        background (float | Unset | VolumeDistanceBackgroundType1): the value beyond the band outside the solid
            (band·voxel_size), or "inf"; inside it is negated
        bricks (int | Unset): stored 8³ bricks
        tiles (int | Unset): brick positions inside and beyond the band (every voxel the negated background)
        active_voxels (int | Unset): voxels in the band
        thickness (float | Unset): method=distance: the thickness used, snapped to 1/256 voxel
    """

    band: int | Unset | VolumeDistanceBandType1 = UNSET
    background: float | Unset | VolumeDistanceBackgroundType1 = UNSET
    bricks: int | Unset = UNSET
    tiles: int | Unset = UNSET
    active_voxels: int | Unset = UNSET
    thickness: float | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        band: int | str | Unset
        if isinstance(self.band, Unset):
            band = UNSET
        elif isinstance(self.band, VolumeDistanceBandType1):
            band = self.band.value
        else:
            band = self.band

        background: float | str | Unset
        if isinstance(self.background, Unset):
            background = UNSET
        elif isinstance(self.background, VolumeDistanceBackgroundType1):
            background = self.background.value
        else:
            background = self.background

        bricks = self.bricks

        tiles = self.tiles

        active_voxels = self.active_voxels

        thickness = self.thickness

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update({})
        if band is not UNSET:
            field_dict["band"] = band
        if background is not UNSET:
            field_dict["background"] = background
        if bricks is not UNSET:
            field_dict["bricks"] = bricks
        if tiles is not UNSET:
            field_dict["tiles"] = tiles
        if active_voxels is not UNSET:
            field_dict["active_voxels"] = active_voxels
        if thickness is not UNSET:
            field_dict["thickness"] = thickness

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)

        def _parse_band(data: object) -> int | Unset | VolumeDistanceBandType1:
            if isinstance(data, Unset):
                return data
            try:
                if not isinstance(data, str):
                    raise TypeError()
                band_type_1 = VolumeDistanceBandType1(data)

                return band_type_1
            except (TypeError, ValueError, AttributeError, KeyError):
                pass
            return cast(int | Unset | VolumeDistanceBandType1, data)

        band = _parse_band(d.pop("band", UNSET))

        def _parse_background(
            data: object,
        ) -> float | Unset | VolumeDistanceBackgroundType1:
            if isinstance(data, Unset):
                return data
            try:
                if not isinstance(data, str):
                    raise TypeError()
                background_type_1 = VolumeDistanceBackgroundType1(data)

                return background_type_1
            except (TypeError, ValueError, AttributeError, KeyError):
                pass
            return cast(float | Unset | VolumeDistanceBackgroundType1, data)

        background = _parse_background(d.pop("background", UNSET))

        bricks = d.pop("bricks", UNSET)

        tiles = d.pop("tiles", UNSET)

        active_voxels = d.pop("active_voxels", UNSET)

        thickness = d.pop("thickness", UNSET)

        volume_distance = cls(
            band=band,
            background=background,
            bricks=bricks,
            tiles=tiles,
            active_voxels=active_voxels,
            thickness=thickness,
        )

        volume_distance.additional_properties = d
        return volume_distance

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
