from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar

from attrs import define as _attrs_define

from ..models.post_v1_volumes_id_morphology_body_kernel import (
    PostV1VolumesIdMorphologyBodyKernel,
)
from ..models.post_v1_volumes_id_morphology_body_op import (
    PostV1VolumesIdMorphologyBodyOp,
)
from ..types import UNSET, Unset

T = TypeVar("T", bound="PostV1VolumesIdMorphologyBody")


@_attrs_define
class PostV1VolumesIdMorphologyBody:
    """
    Attributes:
        op (PostV1VolumesIdMorphologyBodyOp):
        radius (int):
        kernel (PostV1VolumesIdMorphologyBodyKernel | Unset):  Default: PostV1VolumesIdMorphologyBodyKernel.CUBE.
        grow (bool | Unset):  Default: False.
    """

    op: PostV1VolumesIdMorphologyBodyOp
    radius: int
    kernel: PostV1VolumesIdMorphologyBodyKernel | Unset = (
        PostV1VolumesIdMorphologyBodyKernel.CUBE
    )
    grow: bool | Unset = False

    def to_dict(self) -> dict[str, Any]:
        op = self.op.value

        radius = self.radius

        kernel: str | Unset = UNSET
        if not isinstance(self.kernel, Unset):
            kernel = self.kernel.value

        grow = self.grow

        field_dict: dict[str, Any] = {}

        field_dict.update(
            {
                "op": op,
                "radius": radius,
            }
        )
        if kernel is not UNSET:
            field_dict["kernel"] = kernel
        if grow is not UNSET:
            field_dict["grow"] = grow

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        op = PostV1VolumesIdMorphologyBodyOp(d.pop("op"))

        radius = d.pop("radius")

        _kernel = d.pop("kernel", UNSET)
        kernel: PostV1VolumesIdMorphologyBodyKernel | Unset
        if isinstance(_kernel, Unset):
            kernel = UNSET
        else:
            kernel = PostV1VolumesIdMorphologyBodyKernel(_kernel)

        grow = d.pop("grow", UNSET)

        post_v1_volumes_id_morphology_body = cls(
            op=op,
            radius=radius,
            kernel=kernel,
            grow=grow,
        )

        return post_v1_volumes_id_morphology_body
