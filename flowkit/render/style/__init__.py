"""Line styles: the model (``model``), its checks (``check``) and its TOML files (``toml``).

The names users and the renderer import are re-exported here: ``from flowkit.render.style
import Style, Band, load_style`` works as before the split.
"""

from .check import (
    MAX_BANDS,
    MAX_CURVE_POINTS,
    MAX_RANGES,
    StyleError,
    known_colormap,
    percentiles,
    validate,
)
from .model import (
    ANTIALIAS,
    PLACEMENTS,
    PROJECTIONS,
    RGBA,
    STYLE_VERSION,
    UNITS,
    Annotations,
    Band,
    ColorMap,
    Legend,
    LineStyle,
    Pattern,
    Range,
    Shape,
    Style,
    Transfer,
    TransferRange,
    WidthMap,
)
from .toml import (
    camera_from_dict,
    dump_style,
    load_style,
    save_style,
    style_from_dict,
    style_to_dict,
)

__all__ = [
    "ANTIALIAS", "MAX_BANDS", "MAX_CURVE_POINTS", "MAX_RANGES", "PLACEMENTS", "PROJECTIONS",
    "RGBA", "STYLE_VERSION", "UNITS", "Annotations", "Band", "ColorMap", "Legend", "LineStyle",
    "Pattern", "Range", "Shape", "Style", "StyleError", "Transfer", "TransferRange", "WidthMap",
    "camera_from_dict", "dump_style", "known_colormap", "load_style", "percentiles",
    "save_style", "style_from_dict", "style_to_dict", "validate",
]
