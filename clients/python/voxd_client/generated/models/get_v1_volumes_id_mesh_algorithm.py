from enum import StrEnum


class GetV1VolumesIdMeshAlgorithm(StrEnum):
    CUBES = "cubes"
    DUAL_CONTOURING = "dual-contouring"
    MARCHING_CUBES = "marching-cubes"
    SURFACE_NETS = "surface-nets"

    def __str__(self) -> str:
        return str(self.value)
