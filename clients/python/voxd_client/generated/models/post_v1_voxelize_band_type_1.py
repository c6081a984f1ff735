from enum import StrEnum


class PostV1VoxelizeBandType1(StrEnum):
    ALL = "all"

    def __str__(self) -> str:
        return str(self.value)
