from enum import StrEnum


class GetV1VolumesIdPreviewPngAxis(StrEnum):
    X = "x"
    Y = "y"
    Z = "z"

    def __str__(self) -> str:
        return str(self.value)
