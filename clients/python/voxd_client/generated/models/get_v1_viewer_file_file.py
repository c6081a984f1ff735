from enum import StrEnum


class GetV1ViewerFileFile(StrEnum):
    LICENSE_THREE_TXT = "LICENSE-three.txt"
    ORBITCONTROLS_JS = "OrbitControls.js"
    THREE_CORE_MIN_JS = "three.core.min.js"
    THREE_MODULE_MIN_JS = "three.module.min.js"

    def __str__(self) -> str:
        return str(self.value)
