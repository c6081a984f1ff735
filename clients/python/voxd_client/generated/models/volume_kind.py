from enum import StrEnum


class VolumeKind(StrEnum):
    BITS = "bits"
    CHANNELS = "channels"
    DENSITY = "density"
    SPARSE_DISTANCE = "sparse-distance"

    def __str__(self) -> str:
        return str(self.value)
