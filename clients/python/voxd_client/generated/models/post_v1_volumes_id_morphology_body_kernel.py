from enum import StrEnum


class PostV1VolumesIdMorphologyBodyKernel(StrEnum):
    CROSS = "cross"
    CUBE = "cube"
    SPHERE = "sphere"

    def __str__(self) -> str:
        return str(self.value)
