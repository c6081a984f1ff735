from enum import StrEnum


class GetV1VolumesIdDataAttributes(StrEnum):
    MATERIAL = "material"
    RGBA = "rgba"

    def __str__(self) -> str:
        return str(self.value)
