"""The colour legend of a picture, drawn by matplotlib (Agg) as a strip of its own that
``export.render`` puts beside the model area: the two never overlap, whatever the image size.
Ticks from matplotlib's locator (1, 2, 2.5, 5 x 10^k steps), numbers with a common power of
ten when they are very large or small ("x10^-3" above the bar), the title with the unit
written along the bar, and arrows at the ends where values were clipped to the range."""

from __future__ import annotations

import numpy as np

__all__ = ["legend_image"]


def legend_image(size: tuple[int, int], cmap: str, value_range: tuple[float, float], title: str, unit: str,
                 note: str = "", extend: str = "neither") -> np.ndarray:
    """(h, w, 3) uint8 strip of ``size`` (w, h) with a vertical colour bar."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import colors, ticker
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colorbar import ColorbarBase
    from matplotlib.figure import Figure

    w, h = size
    dpi = 100.0
    fig = Figure(figsize=(w / dpi, h / dpi), dpi=dpi, facecolor="white")
    FigureCanvasAgg(fig)
    font = float(np.clip(h / 55.0, 7.5, 13.0))
    # bar: a narrow column left of the tick labels; the title runs along its right side
    bar_w = min(0.16, 18.0 / w * max(1.0, h / 600.0))
    ax = fig.add_axes((0.12, 0.1, bar_w, 0.78))
    lo, hi = value_range
    formatter = ticker.ScalarFormatter(useMathText=True)
    formatter.set_powerlimits((-2, 3))
    bar = ColorbarBase(ax, cmap=matplotlib.colormaps[cmap], norm=colors.Normalize(lo, hi), extend=extend,
                       orientation="vertical", format=formatter)
    bar.ax.tick_params(labelsize=font)
    bar.ax.yaxis.get_offset_text().set_fontsize(font)
    label = f"{title} ({unit})" if unit else title
    bar.set_label(label, fontsize=font * 1.05, labelpad=font * 0.6)
    if note:
        fig.text(0.5, 0.025, note, ha="center", va="bottom", fontsize=font * 0.8, color="0.35", wrap=True)
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    out = np.ascontiguousarray(rgba[:, :, :3])
    if out.shape[:2] != (h, w):  # rounding of the figure size
        fixed = np.full((h, w, 3), 255, np.uint8)
        hh, ww = min(h, out.shape[0]), min(w, out.shape[1])
        fixed[:hh, :ww] = out[:hh, :ww]
        out = fixed
    return out
