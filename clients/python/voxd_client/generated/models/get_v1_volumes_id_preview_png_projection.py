from enum import StrEnum


class GetV1VolumesIdPreviewPngProjection(StrEnum):
    MAX = "max"
    SUM = "sum"

    def __str__(self) -> str:
        return str(self.value)
