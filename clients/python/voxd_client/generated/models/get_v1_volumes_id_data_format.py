from enum import StrEnum


class GetV1VolumesIdDataFormat(StrEnum):
    BINVOX = "binvox"
    NPY = "npy"
    RAW = "raw"
    VDB = "vdb"
    VXL = "vxl"

    def __str__(self) -> str:
        return str(self.value)
