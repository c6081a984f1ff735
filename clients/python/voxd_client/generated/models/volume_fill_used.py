from enum import StrEnum


class VolumeFillUsed(StrEnum):
    FLOOD = "flood"
    PARITY = "parity"
    VOTE = "vote"
    WINDING = "winding"

    def __str__(self) -> str:
        return str(self.value)
