"""Style model, camera, moderngl renderer, colormaps (paper sections 3.1-3.2 and 5)."""

from .camera import Camera
from .context import RenderContextError, create_context, default_context
from .renderer import LineRenderer, default_style, render_file, render_lines, save_png
from .style.check import StyleError
from .style.model import Band, ColorMap, LineStyle, Style, WidthMap
from .style.toml import load_style

__all__ = ["Band", "Camera", "ColorMap", "LineRenderer", "LineStyle", "RenderContextError",
           "Style", "StyleError", "WidthMap", "create_context", "default_context", "default_style",
           "load_style",
           "render_file", "render_lines",
           "save_png"]
