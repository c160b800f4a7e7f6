"""The canvas every figure of :mod:`nurbsmotion.plots` is drawn on: a matplotlib Figure on
an Agg canvas (no pyplot), saved as PNG through a temporary file; titles, axis labels,
legends below the panels, the layout that keeps text inside the figure, and fitting a
panel's view to what it must show. Nothing here knows of runs or paths.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from .._runtime.io import write_output
from ..errors import InvalidArgumentError

_DPI = 110


_PNG_COMPRESSION = 1  # zlib level: level 6 (matplotlib's) took 1.5 x as long for 5 % less


_STYLES = (("C0", "-"), ("C3", "--"), ("C2", "-."), ("C1", ":"), ("C4", "-"), ("C5", "--"))
"""(colour, line style) per run, in order: solid first, as the paper draws its proposed
algorithm solid and the uncompensated one dashed (Figs. 5 and 7)."""


def _output_dir(out_dir) -> Path:
    path = Path(out_dir)
    path.mkdir(parents=True, exist_ok=True)
    return path


def _figure(width: float, height: float):
    """A Figure on its own Agg canvas (no pyplot state) [inch]; no layout engine: the
    panels are placed once, by :func:`_arrange`, when the figure is saved."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=_DPI)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path: Path, overwrite: bool = True) -> Path:
    """Place the panels (:func:`_arrange`), draw ``fig`` and write it as an RGB PNG (the
    figures are opaque: no alpha channel to encode)."""
    from PIL import Image  # matplotlib's own dependency

    _arrange(fig)
    fig.canvas.draw()
    image = Image.fromarray(np.asarray(fig.canvas.buffer_rgba())).convert("RGB")
    write_output(path, lambda h: image.save(h, format="png", dpi=(_DPI, _DPI),
                                            compress_level=_PNG_COMPRESSION),
                 overwrite=overwrite, binary=True)
    return path  # the figure is in no registry: it is freed with its last reference


def _title(ax, text: str, **kwargs) -> None:
    """``ax.set_title`` at a fixed height: :func:`_arrange` makes room for it and lifts it
    above an offset text, so matplotlib need not measure the axis at every draw."""
    ax.set_title(text, y=1.0, **kwargs)


_PAD = 0.08  # [inch] between a block of text and the figure's edge or the next block


def _text_size(text, renderer) -> tuple[float, float]:
    """Width and height [inch] of a Text artist as drawn (0, 0 when empty or hidden)."""
    if not text.get_visible() or not text.get_text():
        return 0.0, 0.0
    box = text.get_window_extent(renderer)
    return box.width / _DPI, box.height / _DPI


def _ticks_in_view(axis) -> list:
    """The major tick locations of ``axis`` inside its view (those a draw draws)."""
    lo, hi = sorted(axis.get_view_interval())
    return [x for x in axis.get_major_locator()() if lo - 1e-9 * (hi - lo) <= x
            <= hi + 1e-9 * (hi - lo)]


def _tick_texts(axis, memo: dict) -> tuple[list, list, str]:
    """``(locations, labels, offset text)`` of the major ticks ``axis`` will draw, from
    its locator and formatter (no tick artists are made); ``memo`` keeps them for one
    :func:`_arrange`, where a panel that keeps its length keeps its ticks."""
    lo, hi = sorted(axis.get_view_interval())
    # what the locator and formatter read: the view and the ticks that fit along it
    key = (axis, lo, hi, axis.get_tick_space())
    if key not in memo:
        locs = _ticks_in_view(axis)
        formatter = axis.get_major_formatter()
        labels = formatter.format_ticks(locs) if locs else []
        offset = formatter.get_offset() if locs and hasattr(formatter, "get_offset") \
            else ""
        memo[key] = locs, labels, offset
    return memo[key]


def _tick_label_size(axis) -> float:
    """Font size of the tick labels of ``axis`` [pt]."""
    import matplotlib as mpl
    from matplotlib.font_manager import FontProperties

    name = "xtick" if axis.axis_name == "x" else "ytick"
    return FontProperties(size=mpl.rcParams[f"{name}.labelsize"]).get_size_in_points()


def _tick_labels(axis, memo: dict) -> tuple[float, float, float]:
    """Widest and tallest major tick label [inch] of ``axis`` as it will be drawn (0 when
    its labels are hidden) and the height of its offset text ("1e-5", "+1000") [inch]
    (``memo`` as :func:`_tick_texts`)."""
    if not axis._major_tick_kw.get("label1On", True):
        return 0.0, 0.0, 0.0
    locs, labels, offset = _tick_texts(axis, memo)
    if not locs:
        return 0.0, 0.0, 0.0
    size = _tick_label_size(axis)
    width = max((_label_extent(label, size)[0] for label in labels if label), default=0.0)
    # a line of text is as tall as "lp" (ascent and descent) whatever it holds
    height = _label_extent("lp", size)[1] + 2.0 / 72
    return width, height, (height if offset else 0.0)


@functools.lru_cache(maxsize=4096)
def _label_box(label: str, size: float) -> tuple[float, float]:
    """Width and height [inch] of the box matplotlib draws one line of text (a tick
    label) of ``size`` [pt] in: its extent as a Text artist, which adds the font's
    ascent and descent to the glyphs' own."""
    text, renderer = _scratch_text()
    text.set_text(label)
    text.set_fontsize(size)
    box = text.get_window_extent(renderer)
    return box.width / _DPI, box.height / _DPI


@functools.lru_cache(maxsize=1)
def _scratch_text():
    """A Text artist on a figure that is never drawn, and its renderer: what
    :func:`_label_box` measures with."""
    fig = _figure(1.0, 1.0)
    return fig.text(0.0, 0.0, ""), fig.canvas.get_renderer()


def _place_axis_labels(ax, memo: dict) -> None:
    """Fix the x and y labels of ``ax`` where matplotlib's draw would put them: beyond
    the spine's ticks and the tick labels, ``axes.labelpad`` away (``Axis.
    _update_label_position``), computed here once from the tick labels' sizes. Left to
    itself, matplotlib would compute every axis's ticks twice more and measure each of
    their labels again at every draw, about a sixth of a figure's drawing time.

    Only a bottom x label and a left y label of a 2-D panel are placed; any other is
    left to matplotlib. ``memo`` as :func:`_tick_texts`.
    """
    if ax.name != "rectilinear":
        return
    for axis, default in ((ax.xaxis, "bottom"), (ax.yaxis, "left")):
        if axis.label_position != default:
            continue
        out = 0.0  # [point] from the spine outwards
        if axis.label.get_visible() and axis.label.get_text():  # else nothing to place
            tick = axis.majorTicks[0]  # every major tick has the same size and pad
            kw = axis._major_tick_kw
            locs, labels, _ = _tick_texts(axis, memo) if axis.get_visible() else ([], [], "")
            if locs and kw.get("tick1On", True):  # the spine's extent holds its ticks
                out = tick.get_tick_padding()
            if locs and kw.get("label1On", True):
                size = _tick_label_size(axis)
                along = 0 if axis is ax.yaxis else 1  # a label's width, or its height
                # an empty label is a point at the pad, as matplotlib measures it
                extent = max((_label_box(text, size)[along] if text else 0.0
                              for text in labels), default=0.0)
                out = max(out, tick._pad + 72 * extent)
            out += axis.labelpad  # [point]
        box = ax.get_position()  # [figure fraction]
        width, height = ax.figure.get_size_inches()
        if axis is ax.xaxis:
            axis.set_label_coords(0.5, -out / 72 / (box.height * height))
        else:
            axis.set_label_coords(-out / 72 / (box.width * width), 0.5)


@functools.lru_cache(maxsize=4096)
def _label_extent(label: str, size: float) -> tuple[float, float]:
    """Width and height [inch] of one line of text (a tick label) of ``size`` [pt]; the
    same labels recur on every panel, so each is measured once."""
    from matplotlib.backends.backend_agg import RendererAgg
    from matplotlib.cbook import is_math_text
    from matplotlib.font_manager import FontProperties

    renderer = RendererAgg(1, 1, _DPI)  # draws nothing: measures with the same fonts
    w, h, _ = renderer.get_text_width_height_descent(label, FontProperties(size=size),
                                                     ismath=is_math_text(label))
    return w / _DPI, h / _DPI


def _fixed_text(ax, renderer) -> tuple[float, float, float]:
    """Width of the y label, height of the x label and of the tallest title of ``ax``
    [inch]: what does not change as :func:`_arrange` moves the panels."""
    if ax.name == "3d":
        return 0.0, 0.0, max(_text_size(t, renderer)[1] for t in (ax.title, ax._left_title))
    return (_text_size(ax.yaxis.label, renderer)[0], _text_size(ax.xaxis.label, renderer)[1],
            max(_text_size(t, renderer)[1] for t in (ax.title, ax._left_title,
                                                      ax._right_title)))


def _decorations(ax, fixed: tuple[float, float, float],
                 memo: dict) -> tuple[float, float, float, float, float]:
    """Room [inch] the text of a panel takes outside its frame: left, right, bottom, top,
    and the height of the y offset text above it (which the titles must clear).
    ``fixed`` is its :func:`_fixed_text`, ``memo`` as :func:`_tick_texts`."""
    import matplotlib as mpl

    ylabel, xlabel, titles = fixed
    if ax.name == "3d":  # its labels lie inside its square box
        return 0.2, 0.2, 0.2, titles + 6 / 72, 0.0
    pad = (mpl.rcParams["xtick.major.size"] + mpl.rcParams["xtick.major.pad"]) / 72
    xw, xh, xoff = _tick_labels(ax.xaxis, memo)
    yw, _, yoff = _tick_labels(ax.yaxis, memo)
    labelpad = mpl.rcParams["axes.labelpad"] / 72
    left = (yw + pad if yw else 0.0) + (ylabel + labelpad if ylabel else 0.0)
    bottom = (xh + pad if xh else 0.0) + (xlabel + labelpad if xlabel else 0.0) + xoff
    top = max(titles + mpl.rcParams["axes.titlepad"] / 72 if titles else 0.0, yoff)
    if titles and yoff:
        top += yoff
    right = 0.5 * xw  # the last x tick label reaches past the frame by half its width
    return left, right, bottom, top, yoff


def _arrange(fig) -> None:
    """Place the panels of ``fig`` (one grid of subplots) so that their labels, titles,
    the suptitle and the figure's legend fit, from the size of each text.

    A fixed layout computed once: matplotlib's constrained layout measures every panel
    with all its ticks at every draw, which was most of the time of a figure.
    """
    renderer = fig.canvas.get_renderer()
    width, height = fig.get_size_inches()
    axes = [ax for ax in fig.axes if ax.get_subplotspec() is not None]
    if not axes:
        return
    grid = axes[0].get_subplotspec().get_gridspec()
    n_rows, n_cols = grid.get_geometry()
    top_text = 0.0
    for t in fig.texts:  # the suptitle
        t.set_y(1.0 - _PAD / height)
        top_text = max(top_text, _text_size(t, renderer)[1] + _PAD)
    legend = sum(_text_size_box(lg, renderer) + _PAD for lg in fig.legends)
    fixed = {ax: _fixed_text(ax, renderer) for ax in axes}
    memo: dict = {}
    for _ in range(2):  # the tick labels depend on the panel sizes: once more
        deco = {ax: _decorations(ax, fixed[ax], memo) for ax in axes}

        def most(index, keep):
            return max([deco[ax][index] for ax in axes if keep(ax.get_subplotspec())],
                       default=0.0)

        left = most(0, lambda s: s.colspan.start == 0) + _PAD
        right = most(1, lambda s: s.colspan.stop == n_cols) + _PAD
        bottom = most(2, lambda s: s.rowspan.stop == n_rows) + _PAD + legend
        top = most(3, lambda s: s.rowspan.start == 0) + _PAD + top_text
        w_gap = (most(0, lambda s: s.colspan.start > 0)
                 + most(1, lambda s: s.colspan.stop < n_cols) + _PAD)
        h_gap = (most(2, lambda s: s.rowspan.stop < n_rows)
                 + most(3, lambda s: s.rowspan.start > 0) + _PAD)
        panel_w = max((width - left - right - (n_cols - 1) * w_gap) / n_cols, 0.3)
        panel_h = max((height - top - bottom - (n_rows - 1) * h_gap) / n_rows, 0.3)
        grid.update(left=min(left / width, 0.45), right=max(1 - right / width, 0.55),
                    bottom=min(bottom / height, 0.45), top=max(1 - top / height, 0.55),
                    wspace=w_gap / panel_w, hspace=h_gap / panel_h)
        for ax in axes:  # GridSpec.update moves the panels of pyplot's figures only
            ax.set_position(ax.get_subplotspec().get_position(fig))
    for ax in axes:  # titles above an offset text ("1e-5") at the top of the y axis
        lift = deco[ax][4] / (ax.get_position().height * height)
        for t in (ax.title, ax._left_title, ax._right_title):
            t.set_y(1.0 + lift)
        _place_axis_labels(ax, memo)


def _text_size_box(artist, renderer) -> float:
    """Height [inch] of an artist's extent (a legend)."""
    return artist.get_window_extent(renderer).height / _DPI


def _axis_labels(n_axes: int, axis_names=None) -> tuple[str, ...]:
    if axis_names is not None:
        names = tuple(str(a) for a in axis_names)
        if len(names) < n_axes:
            raise InvalidArgumentError(f"{n_axes} axes need {n_axes} axis_names, got {names}")
        return names[:n_axes]
    default = ("x", "y", "z")
    return tuple(default[j] if j < 3 else f"axis {j}" for j in range(n_axes))


def _feed_text(feed: float, per_unit: float, unit: str) -> str:
    """``F = 1000 mm/s (1e+06 pulse/s)``."""
    return f"F = {feed / per_unit:.4g} {unit}/s ({feed:.3g} pulse/s)"


def _legend_below(fig, axes, ncol: int | None = None) -> None:
    """One legend for the figure, below every panel, from the handles of ``axes``."""
    handles, labels = [], []
    for ax in np.atleast_1d(axes).ravel():
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels and not lab.startswith("_"):
                handles.append(h)
                labels.append(lab)
    if handles:
        fig.legend(handles, labels, loc="lower center", fontsize="small",
                   bbox_to_anchor=(0.5, _PAD / fig.get_figheight()),
                   ncol=ncol or min(len(labels), 4))


def _fit_in_view(ax, artists) -> None:
    """Widen the data limits of ``ax`` so that ``artists`` (text boxes) lie inside the axes,
    not over a neighbouring panel or its labels."""
    if not artists:
        return
    renderer = ax.figure.canvas.get_renderer()
    for _ in range(2):  # the limits change the scale: once more on the new scale
        ax.apply_aspect()  # what a draw would do first (equal scales adjust the limits)
        inverse = ax.transData.inverted()
        for a in artists:
            corners = inverse.transform(a.get_window_extent(renderer).get_points())
            ax.update_datalim(corners)
        ax.autoscale_view()
