from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

T = TypeVar("T", bound="GetV1VolumesIdNormalsResponse200")


@_attrs_define
class GetV1VolumesIdNormalsResponse200:
    """
    Attributes:
        normals (list[list[float] | None]):
    """

    normals: list[list[float] | None]
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        normals = []
        for normals_item_data in self.normals:
            normals_item: list[float] | None
            if isinstance(normals_item_data, list):
                normals_item = normals_item_data

            else:
                normals_item = normals_item_data
            normals.append(normals_item)

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "normals": normals,
            }
        )

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        normals = []
        _normals = d.pop("normals")
        for normals_item_data in _normals:

            def _parse_normals_item(data: object) -> list[float] | None:
                if data is None:
                    return data
                try:
                    if not isinstance(data, list):
                        raise TypeError()
                    normals_item_type_0 = cast(list[float], data)

                    return normals_item_type_0
                except (TypeError, ValueError, AttributeError, KeyError):
                    pass
                return cast(list[float] | None, data)

            normals_item = _parse_normals_item(normals_item_data)

            normals.append(normals_item)

        get_v1_volumes_id_normals_response_200 = cls(
            normals=normals,
        )

        get_v1_volumes_id_normals_response_200.additional_properties = d
        return get_v1_volumes_id_normals_response_200

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
