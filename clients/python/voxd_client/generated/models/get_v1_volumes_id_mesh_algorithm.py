from enum import StrEnum


class GetV1VolumesIdMeshAlgorithm(StrEnum):
    CUBES = "cubes"

    def __str__(self) -> str:
        return str(self.value)
