from enum import StrEnum


class VolumeSourceCompression(StrEnum):
    GZIP = "gzip"
    ZIP = "zip"

    def __str__(self) -> str:
        return str(self.value)
