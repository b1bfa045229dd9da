"""Style model, camera, moderngl renderer, colormaps."""
