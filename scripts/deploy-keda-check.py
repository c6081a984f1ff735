"""Checks a KEDA ScaledObject against KEDA's CRD schema, strictly.

The schema comes from PyPI's cloudcoil-models-keda (pydantic models generated from KEDA's
CRDs). Those models accept unknown properties; here every model forbids them, so a misspelt
field fails as `kubernetes-validate --strict` would. A trigger's `metadata` is a free map in
the CRD and stays unchecked.  Usage: deploy-keda-check.py FILE...
"""

import sys

import pydantic
import yaml
from cloudcoil.models.keda import v1alpha1

MODELS = [
    c
    for c in vars(v1alpha1).values()
    if isinstance(c, type) and issubclass(c, pydantic.BaseModel)
]
# Nested models are inlined when a parent is built: rebuild until every level forbids extras.
for _ in range(3):
    for model in MODELS:
        model.model_config["extra"] = "forbid"
        model.model_rebuild(force=True)

failed = False
for path in sys.argv[1:]:
    with open(path, encoding="utf-8") as f:
        for doc in yaml.safe_load_all(f):
            if not doc or doc.get("kind") != "ScaledObject":
                continue
            name = doc.get("metadata", {}).get("name")
            try:
                v1alpha1.ScaledObject.model_validate(doc)
                print(f"INFO {path} passed for resource scaledobject/{name} (KEDA 2.16 CRD)")
            except pydantic.ValidationError as e:
                print(f"ERROR {path} scaledobject/{name}: {e}")
                failed = True
sys.exit(1 if failed else 0)
