from enum import StrEnum


class PostV1VolumesIdMorphologyBodyOp(StrEnum):
    CLOSE = "close"
    DILATE = "dilate"
    ERODE = "erode"
    OPEN = "open"

    def __str__(self) -> str:
        return str(self.value)
