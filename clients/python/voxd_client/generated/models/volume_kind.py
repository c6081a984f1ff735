from enum import StrEnum


class VolumeKind(StrEnum):
    BITS = "bits"
    DENSITY = "density"

    def __str__(self) -> str:
        return str(self.value)
