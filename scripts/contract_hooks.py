"""Schemathesis hooks for scripts/contract.sh.

A query value with no form on the wire (null, an empty list or object, a list holding lists or
objects) is dropped by the HTTP client, so a case generated to break the document could reach
the service as one that keeps to it (an extra property of an exploded object parameter, say
`view` or `grid`, whose value is `[{}]`). Such values are sent as their JSON text instead: what
was generated is what is sent.
"""

import json

import schemathesis

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
