"""The forms a style length takes ('2.5px', '1/200d', '0.1z', '0.05 m'; lengths.py says what
each means), parsed: the style model checks its lengths with this module, and lengths.py, which
builds on the model, resolves them for a picture."""

from __future__ import annotations

import math
import re

METRES = {"m": 1.0, "cm": 0.01, "mm": 1e-3, "km": 1e3}
KINDS = ("px", "d", "z", *METRES)
_FORM = re.compile(r"^\s*([0-9.eE+-]+)(?:\s*/\s*([0-9.eE+-]+))?\s*(px|d|z|m|cm|mm|km)\s*$")
FORMS = ("a number in the style's units, or a string: '2px' (screen pixels), '1/200d' (a fraction "
         "of the domain diagonal), '0.1z' (a fraction of the scene's depth range) or '0.05 m' "
         "(world units: m, cm, mm, km)")


def parse(text: str) -> tuple[float, str] | None:
    """``"1/200d"`` -> (0.005, "d"); None when ``text`` is not such a length."""
    m = _FORM.match(text) if isinstance(text, str) else None
    if m is None:
        return None
    try:
        value = float(m[1]) / float(m[2]) if m[2] else float(m[1])
    except (ValueError, ZeroDivisionError):
        return None
    return (value, m[3]) if math.isfinite(value) and value >= 0 else None
