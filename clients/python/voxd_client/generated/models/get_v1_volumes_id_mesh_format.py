from enum import StrEnum


class GetV1VolumesIdMeshFormat(StrEnum):
    GLB = "glb"
    OBJ = "obj"
    PLY = "ply"
    STL = "stl"

    def __str__(self) -> str:
        return str(self.value)
