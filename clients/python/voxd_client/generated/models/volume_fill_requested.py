from enum import StrEnum


class VolumeFillRequested(StrEnum):
    AUTO = "auto"
    FLOOD = "flood"
    PARITY = "parity"
    VOTE = "vote"
    WINDING = "winding"

    def __str__(self) -> str:
        return str(self.value)
