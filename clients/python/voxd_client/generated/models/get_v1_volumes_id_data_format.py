from enum import StrEnum


class GetV1VolumesIdDataFormat(StrEnum):
    BINVOX = "binvox"
    INDICES = "indices"
    NPY = "npy"
    POINTS = "points"
    RAW = "raw"
    VDB = "vdb"
    VOX = "vox"
    VXL = "vxl"

    def __str__(self) -> str:
        return str(self.value)
