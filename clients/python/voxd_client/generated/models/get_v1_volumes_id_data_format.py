from enum import StrEnum


class GetV1VolumesIdDataFormat(StrEnum):
    BINVOX = "binvox"
    NPY = "npy"
    RAW = "raw"
    VXL = "vxl"

    def __str__(self) -> str:
        return str(self.value)
