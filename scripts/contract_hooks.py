"""Schemathesis hooks for scripts/contract.sh.

A query value with no form on the wire (null, an empty list or object, a list holding lists or
objects) is dropped by the HTTP client, so a case generated to break the document could reach
the service as one that keeps to it (a parameter whose value is `[{}]` would be left out). Such values are sent as their JSON text instead: what
was generated is what is sent.
"""

import json

import schemathesis
from schemathesis.core.media_types import YAML_MEDIA_TYPES

_SCALARS = (str, int, float, bool)


def _has_wire_form(value):
    if isinstance(value, _SCALARS):
        return True
    if isinstance(value, (list, tuple)):
        return bool(value) and all(isinstance(x, _SCALARS) for x in value)
    return False


@schemathesis.hook
def map_case(ctx, case):
    if case.query:
        case.query = {
            k: v if _has_wire_form(v) else json.dumps(v) for k, v in case.query.items()
        }
    return case


# GET /openapi.yaml answers a YAML document, which the contract types as what a client gets: a
# string (openapi.yaml says why: generated clients read it as text). Schemathesis would parse the
# YAML and check the object it holds against that; it checks the text instead. (Every YAML type
# is registered again: the first registered of a family answers for all of it.)
@schemathesis.deserializer(*YAML_MEDIA_TYPES)
def yaml_as_text(ctx, response):
    return response.content.decode("utf-8")
