from enum import StrEnum


class PostV1VoxelizeMethod(StrEnum):
    CONSERVATIVE = "conservative"
    DENSITY = "density"
    DISTANCE = "distance"
    INTERIOR = "interior"
    SDF = "sdf"
    SOLID = "solid"
    SURFACE = "surface"

    def __str__(self) -> str:
        return str(self.value)
