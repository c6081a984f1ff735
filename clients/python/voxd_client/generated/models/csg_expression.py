from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self, TypeVar, cast

from attrs import define as _attrs_define

from ..models.csg_expression_op import CsgExpressionOp

T = TypeVar("T", bound="CsgExpression")


@_attrs_define
class CsgExpression:
    """{"op", "operands"}: each operand a volume id or an expression; nested at most 32 deep, and
    the whole body at most 65536 bytes as JSON (it is kept as the result's provenance)

        Attributes:
            op (CsgExpressionOp):
            operands (list[CsgExpression | str]):
    """

    op: CsgExpressionOp
    operands: list[CsgExpression | str]

    def to_dict(self) -> dict[str, Any]:
        op = self.op.value

        operands = []
        for operands_item_data in self.operands:
            operands_item: dict[str, Any] | str
            if isinstance(operands_item_data, CsgExpression):
                operands_item = operands_item_data.to_dict()
            else:
                operands_item = operands_item_data
            operands.append(operands_item)

        field_dict: dict[str, Any] = {}

        field_dict.update(
            {
                "op": op,
                "operands": operands,
            }
        )

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        d = dict(src_dict)
        op = CsgExpressionOp(d.pop("op"))

        operands = []
        _operands = d.pop("operands")
        for operands_item_data in _operands:

            def _parse_operands_item(data: object) -> CsgExpression | str:
                try:
                    if not isinstance(data, dict):
                        raise TypeError()
                    componentsschemas_csg_operand_type_1 = CsgExpression.from_dict(data)

                    return componentsschemas_csg_operand_type_1
                except (TypeError, ValueError, AttributeError, KeyError):
                    pass
                return cast(CsgExpression | str, data)

            operands_item = _parse_operands_item(operands_item_data)

            operands.append(operands_item)

        csg_expression = cls(
            op=op,
            operands=operands,
        )

        return csg_expression
