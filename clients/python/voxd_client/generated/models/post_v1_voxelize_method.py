from enum import StrEnum


class PostV1VoxelizeMethod(StrEnum):
    CONSERVATIVE = "conservative"
    DENSITY = "density"
    INTERIOR = "interior"
    SOLID = "solid"
    SURFACE = "surface"

    def __str__(self) -> str:
        return str(self.value)
