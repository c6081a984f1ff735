from enum import StrEnum


class PostV1VoxelizeFormat(StrEnum):
    GLB = "glb"
    GLTF = "gltf"
    OBJ = "obj"
    PLY = "ply"
    STL = "stl"

    def __str__(self) -> str:
        return str(self.value)
