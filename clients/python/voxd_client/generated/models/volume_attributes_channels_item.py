from enum import StrEnum


class VolumeAttributesChannelsItem(StrEnum):
    MATERIAL = "material"
    RGBA = "rgba"

    def __str__(self) -> str:
        return str(self.value)
