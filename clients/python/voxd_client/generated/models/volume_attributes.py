from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Self, TypeVar

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..models.volume_attributes_channels_item import VolumeAttributesChannelsItem
from ..types import UNSET, Unset

if TYPE_CHECKING:
    from ..models.volume_attributes_materials_item import VolumeAttributesMaterialsItem


T = TypeVar("T", bound="VolumeAttributes")


@_attrs_define
class VolumeAttributes:
    """volumes of kind channels: their channels and the material table

    Attributes:
        channels (list[VolumeAttributesChannelsItem]):
        materials (list[VolumeAttributesMaterialsItem] | Unset): with a material channel: the mesh's materials, id =
            index
    """

    channels: list[VolumeAttributesChannelsItem]
    materials: list[VolumeAttributesMaterialsItem] | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        channels = []
        for channels_item_data in self.channels:
            channels_item = channels_item_data.value
            channels.append(channels_item)

        materials: list[dict[str, Any]] | Unset = UNSET
        if not isinstance(self.materials, Unset):
            materials = []
            for materials_item_data in self.materials:
                materials_item = materials_item_data.to_dict()
                materials.append(materials_item)

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "channels": channels,
            }
        )
        if materials is not UNSET:
            field_dict["materials"] = materials

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        from ..models.volume_attributes_materials_item import (
            VolumeAttributesMaterialsItem,
        )

        d = dict(src_dict)
        channels = []
        _channels = d.pop("channels")
        for channels_item_data in _channels:
            channels_item = VolumeAttributesChannelsItem(channels_item_data)

            channels.append(channels_item)

        _materials = d.pop("materials", UNSET)
        materials: list[VolumeAttributesMaterialsItem] | Unset = UNSET
        if _materials is not UNSET:
            materials = []
            for materials_item_data in _materials:
                materials_item = VolumeAttributesMaterialsItem.from_dict(
                    materials_item_data
                )

                materials.append(materials_item)

        volume_attributes = cls(
            channels=channels,
            materials=materials,
        )

        volume_attributes.additional_properties = d
        return volume_attributes

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
