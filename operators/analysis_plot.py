"""Pictures for the analysis operators, drawn with NumPy only (Blender ships NumPy but not
matplotlib): the four shape-space embeddings as scatter plots in one RGBA image, and the colour
maps of the distortion attributes. No bpy here, so it is tested without Blender.

Text uses a 5×7 bitmap font of the characters the plots need (hand-written: there is no text
rasterizer in NumPy and Blender's blf draws only into the UI, not into an image's pixels).
"""

from __future__ import annotations

import numpy as np

_FONT = {
    "0": ".###.#...##..###.#.###..##...#.###.", "1": "..#...##....#....#....#....#...###.",
    "2": ".###.#...#....#...#...#...#...#####", "3": "####.....#....#.###.....#....#####.",
    "4": "...#...##..#.#.#..#.#####...#....#.", "5": "#####.....####.....#....##...#.###.",
    "6": "..##..#...#....####.#...##...#.###.", "7": "#####....#...#...#...#....#....#...",
    "8": ".###.#...##...#.###.#...##...#.###.", "9": ".###.#...##...#.####....#...#..##..",
    ".": "..............................##...", "%": "##...##..#...#...#...#...#..##...##",
    "-": "................###................", " ": "." * 35,
    "A": ".###.#...##...#######...##...##...#", "C": ".###.#...##....#....#....#...#.###.",
    "D": "####.#...##...##...##...##...#####.", "E": "######....#....####.#....#....#####",
    "F": "######....#....####.#....#....#....", "I": ".###...#....#....#....#....#...###.",
    "K": "#...##..#.#.#..##...#.#..#..#.#...#", "L": "#....#....#....#....#....#....#####",
    "M": "#...###.###.#.##...##...##...##...#", "N": "#...###..##.#.##..###...##...##...#",
    "O": ".###.#...##...##...##...##...#.###.", "P": "####.#...##...#####.#....#....#....",
    "R": "####.#...##...#####.#.#..#..#.#...#", "S": ".####.....#.....###.....#....#####.",
    "T": "#####..#....#....#....#....#....#..", "Y": "#...##...#.#.#...#....#....#....#..",
    "(": "...#...#...#....#....#.....#.....#.", ")": ".#.....#.....#....#....#...#...#...",
    "/": "....#...#...#...#...#...#...#......", ":": ".......##...##.........##...##.....",
}
GLYPH = {char: np.array([c == "#" for c in rows[:35].ljust(35, ".")], dtype=bool).reshape(7, 5)
         for char, rows in _FONT.items()}

# Colour maps as sRGB control points (matplotlib's viridis and a blue–white–red diverging map).
_VIRIDIS = np.array([[0.267, 0.005, 0.329], [0.283, 0.141, 0.458], [0.254, 0.265, 0.530],
                     [0.207, 0.372, 0.553], [0.164, 0.471, 0.558], [0.128, 0.567, 0.551],
                     [0.135, 0.659, 0.518], [0.267, 0.749, 0.441], [0.478, 0.821, 0.318],
                     [0.741, 0.873, 0.150], [0.993, 0.906, 0.144]])
_DIVERGING = np.array([[0.230, 0.299, 0.754], [0.552, 0.690, 0.996], [0.865, 0.865, 0.865],
                       [0.958, 0.604, 0.483], [0.706, 0.016, 0.150]])


def colormap(values: np.ndarray, name: str = "viridis") -> np.ndarray:
    """sRGB colours ``(..., 3)`` of values in ``[0, 1]`` (clipped)."""
    points = _VIRIDIS if name == "viridis" else _DIVERGING
    x = np.clip(np.asarray(values, dtype=np.float64), 0.0, 1.0) * (len(points) - 1)
    low = np.minimum(np.floor(x).astype(int), len(points) - 2)
    frac = (x - low)[..., None]
    return points[low] * (1 - frac) + points[low + 1] * frac


def srgb_to_linear(rgb: np.ndarray) -> np.ndarray:
    """Blender stores float colours and image pixels (non-colour-managed buffers aside) linearly."""
    rgb = np.asarray(rgb)
    return np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)


#: A map whose values (98th percentile) span less than this is round-off and drawn in its neutral
#: colour, as one whose every value is within its round-off (``scalar_colors``): a pose that does
#: not change the base has distortions of round-off size (1e-16 in double precision, 1e-6 from
#: Blender's single-precision keys), which scaled to their own 98th percentile came out as
#: full-contrast noise.
MIN_COLOUR_RANGE = 1e-6


def scalar_colors(values: np.ndarray, *, diverging: bool, floor: float | None = None,
                  round_off: np.ndarray | float = 0.0) -> np.ndarray:
    """Linear RGBA ``(n, 4)`` for a distortion map: diverging maps are symmetric about 0 (or about
    ``floor``) and scaled to the 98th percentile of the magnitude so one outlier does not wash the
    map out; sequential maps run from ``floor`` (default the minimum) to the 98th percentile. The
    percentile is of the values beyond ``round_off`` (per value, or one size: what the rounding of
    the coordinates alone makes, ``core.Distortion.round_off_vertices``); a map with none, or a
    span of at most :data:`MIN_COLOUR_RANGE`, is all neutral."""
    values = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(values)
    if floor is not None:
        centre = floor
    else:
        centre = 0.0 if diverging or not finite.any() else float(values[finite].min())
    offsets = values[finite] - centre
    magnitudes = np.abs(offsets) if diverging else offsets
    # the values beyond their round-off set the scale: a swell on 0.6 % of a sheet is the map, not
    # the round-off around it (scaled with it, it was neutral)
    real = magnitudes[magnitudes > np.broadcast_to(round_off, values.shape)[finite]]
    scale = float(np.percentile(real, 98)) if real.size else 0.0
    if scale <= MIN_COLOUR_RANGE:
        t = np.full(values.shape, 0.5 if diverging else 0.0)
    else:
        t = 0.5 + 0.5 * (values - centre) / scale if diverging else (values - centre) / scale
    rgb = colormap(t, "diverging" if diverging else "viridis")
    rgba = np.ones(values.shape + (4,))
    rgba[..., :3] = srgb_to_linear(rgb)
    return rgba


class Canvas:
    """An RGB float image ``(height, width, 3)``, row 0 at the top, with a few drawing primitives."""

    def __init__(self, width: int, height: int, background=(1.0, 1.0, 1.0)):
        self.pixels = np.empty((height, width, 3))
        self.pixels[:] = background

    @property
    def height(self) -> int:
        return self.pixels.shape[0]

    @property
    def width(self) -> int:
        return self.pixels.shape[1]

    def rectangle(self, x0, y0, x1, y1, color, *, fill=False):
        x0, x1 = sorted((int(x0), int(x1)))
        y0, y1 = sorted((int(y0), int(y1)))
        if fill:
            self.pixels[max(y0, 0):y1 + 1, max(x0, 0):x1 + 1] = color
            return
        for x, y, xx, yy in ((x0, y0, x1, y0), (x0, y1, x1, y1), (x0, y0, x0, y1), (x1, y0, x1, y1)):
            self.line(x, y, xx, yy, color)

    def line(self, x0, y0, x1, y1, color):
        steps = int(max(abs(x1 - x0), abs(y1 - y0), 1))
        xs = np.rint(np.linspace(x0, x1, steps + 1)).astype(int)
        ys = np.rint(np.linspace(y0, y1, steps + 1)).astype(int)
        keep = (xs >= 0) & (xs < self.width) & (ys >= 0) & (ys < self.height)
        self.pixels[ys[keep], xs[keep]] = color

    def disc(self, x, y, radius, color, outline=(0.0, 0.0, 0.0)):
        r = int(np.ceil(radius)) + 1
        yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
        distance = np.hypot(xx, yy)
        for mask, fill in ((distance <= radius + 0.5, outline), (distance <= radius - 0.5, color)):
            px, py = (xx[mask] + int(round(x))), (yy[mask] + int(round(y)))
            keep = (px >= 0) & (px < self.width) & (py >= 0) & (py < self.height)
            self.pixels[py[keep], px[keep]] = fill

    def text(self, x, y, string, color=(0.0, 0.0, 0.0), scale=2):
        """Draw ``string`` (upper-cased; unknown characters as spaces) with its top-left at (x, y)."""
        for i, char in enumerate(str(string).upper()):
            glyph = np.kron(GLYPH.get(char, GLYPH[" "]), np.ones((scale, scale), dtype=bool))
            gx, gy = int(x + i * 6 * scale), int(y)
            rows, cols = np.nonzero(glyph)
            px, py = gx + cols, gy + rows
            keep = (px >= 0) & (px < self.width) & (py >= 0) & (py < self.height)
            self.pixels[py[keep], px[keep]] = color

    @staticmethod
    def text_width(string, scale=2) -> int:
        return len(str(string)) * 6 * scale

    def rgba_bottom_up(self) -> np.ndarray:
        """Linear RGBA float32 ``(height, width, 4)`` with row 0 at the bottom (Blender's order)."""
        out = np.ones((self.height, self.width, 4), dtype=np.float32)
        out[..., :3] = srgb_to_linear(self.pixels[::-1])
        return out


PANEL_TITLES = {"area": "AREA", "conformal": "CONFORMAL", "offset_area": "OFFSET AREA",
                "offset_conformal": "OFFSET CONFORMAL"}


def shape_space_image(coordinates: dict, variance: dict, *, panel: int = 300, highlight: int | None = None) -> Canvas:
    """The four embeddings side by side as the paper draws them (Figs. 7 and 9): one panel per
    kind, points coloured by pose order (viridis, first pose dark), a light line through them in
    that order, axes labelled with their share of the variance. ``coordinates[kind]``: ``(N, 2)``;
    ``variance[kind]``: the explained variance ratios; ``highlight``: a pose index drawn larger."""
    kinds = list(coordinates)
    margin, title = 12, 30
    canvas = Canvas(len(kinds) * (panel + margin) + margin, panel + title + 2 * margin)
    for column, kind in enumerate(kinds):
        xy = np.asarray(coordinates[kind], dtype=np.float64)
        n = len(xy)
        left, top = margin + column * (panel + margin), title + margin
        canvas.rectangle(left, top, left + panel, top + panel, (0.35, 0.35, 0.35))
        canvas.text(left + (panel - Canvas.text_width(PANEL_TITLES[kind])) // 2, 8, PANEL_TITLES[kind])
        ratio = np.asarray(variance[kind], dtype=np.float64)
        share = [f"{100 * ratio[i]:.1f}%" if i < ratio.size else "-" for i in range(2)]
        canvas.text(left + 6, top + panel - 20, f"PC1 {share[0]}", (0.2, 0.2, 0.2))
        canvas.text(left + 6, top + 6, f"PC2 {share[1]}", (0.2, 0.2, 0.2))
        low, high = xy.min(axis=0), xy.max(axis=0)
        size = np.where(high - low > 0, high - low, 1.0)
        inner = panel - 60
        px = left + 30 + (xy[:, 0] - low[0]) / size[0] * inner
        py = top + 30 + (1.0 - (xy[:, 1] - low[1]) / size[1]) * inner
        for i in range(n - 1):
            canvas.line(px[i], py[i], px[i + 1], py[i + 1], (0.8, 0.8, 0.8))
        colors = colormap(np.arange(n) / max(n - 1, 1))
        for i in range(n):
            canvas.disc(px[i], py[i], 7.5 if i == highlight else 4.5, colors[i],
                        outline=(0.9, 0.1, 0.1) if i == highlight else (0.0, 0.0, 0.0))
    return canvas
