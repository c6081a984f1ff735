from enum import StrEnum


class CsgExpressionOp(StrEnum):
    DIFFERENCE = "difference"
    INTERSECTION = "intersection"
    UNION = "union"
    XOR = "xor"

    def __str__(self) -> str:
        return str(self.value)
