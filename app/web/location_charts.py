"""A location's chart for the catalogue page: beta(a) over its crack's growth, and beside it
the residual strength against the crack with the limit stress and a_crit, the cracks where
net-section yield sets it shaded (app.web.catalogue computes the curves; app.web.charts draws
and styles every chart).  Elements carry ids (`beta`, `residual-strength`, `limit-stress`,
`a-crit`, `net-section-yield`) for tools and tests to find."""

from __future__ import annotations

from typing import TYPE_CHECKING

from app.web import format as fmt
from app.web.catalogue import Curves
from app.web.charts import _CRITICAL, _INK, ImageFormat, _draw, _mm

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


def location_chart(name: str, curves: Curves, *, image_format: ImageFormat) -> bytes:
    """The location's beta(a) and, where it has a toughness, residual-strength chart."""
    return _draw(lambda: _figure(name, curves), image_format)


def _figure(name: str, curves: Curves) -> Figure:
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9, 3.0), layout="constrained")
    beta_axes, axes = figure.subplots(1, 2)
    _style(beta_axes, f"{name}: beta(a)", "beta")
    (line,) = beta_axes.plot(_mm(curves.beta_crack_m), curves.beta, color=_INK, linewidth=1.6)
    line.set_gid("beta")
    beta_axes.plot(_mm(curves.beta_crack_m), curves.beta, "o", color=_INK, markersize=2.5)
    _critical_at(beta_axes, curves.critical_crack_m)
    if curves.strength_crack_m is None or curves.strength_mpa is None:
        axes.set_axis_off()
        axes.text(
            0.5,
            0.5,
            "No toughness (fracture_toughness_mpa_sqrt_m or a material):\n"
            "the residual strength is not computed",
            ha="center",
            va="center",
            color="#486581",
            transform=axes.transAxes,
        )
        return figure
    _style(axes, f"{name}: residual strength", "residual strength (MPa)")
    (strength,) = axes.plot(
        _mm(curves.strength_crack_m), curves.strength_mpa, color=_INK, linewidth=1.6
    )
    strength.set_gid("residual-strength")
    if curves.strength_criterion is not None and "net_section_yield" in curves.strength_criterion:
        yielding = axes.fill_between(
            _mm(curves.strength_crack_m),
            0,
            curves.strength_mpa,
            where=[c == "net_section_yield" for c in curves.strength_criterion],
            color=_INK,
            alpha=0.12,
            linewidth=0,
            label="net-section yield governs",
        )
        yielding.set_gid("net-section-yield")
    if curves.limit_stress_mpa is None:  # said in the legend (a blank handle), no line drawn
        axes.plot([], [], " ", label="no limit stress given")
    else:
        limit = axes.axhline(
            curves.limit_stress_mpa,
            color="#486581",
            linestyle=":",
            linewidth=1.2,
            label=f"limit stress {curves.limit_stress_mpa:g} MPa",
        )
        limit.set_gid("limit-stress")
    _critical_at(axes, curves.critical_crack_m)
    axes.set_ylim(bottom=0)
    # opaque, so that the a_crit line, which often runs under it, does not strike its text
    legend = axes.legend(loc="upper right", fontsize=8, frameon=True, framealpha=0.92)
    legend.get_frame().set_linewidth(0)
    return figure


def _style(axes: Axes, title: str, ylabel: str) -> None:
    axes.set_title(title, loc="left")
    axes.set_xlabel("crack length (mm)")
    axes.set_ylabel(ylabel)
    axes.grid(True, linewidth=0.6)
    axes.spines[["top", "right"]].set_visible(False)


def _critical_at(axes: Axes, critical_crack_m: float) -> None:
    line = axes.axvline(
        critical_crack_m * 1000,
        color=_CRITICAL,
        linestyle="--",
        linewidth=1.2,
        label=f"a_crit {fmt.mm(critical_crack_m)} mm",
    )
    line.set_gid("a-crit")
