"""A location's chart for the catalogue page: beta(a) over its crack's growth with the case's
validity limit, and beside it the residual strength against the crack with the limit stress
and a_crit, the cracks where net-section yield sets it shaded (app.web.catalogue computes the
curves; app.web.charts draws and styles every chart).  Each legend lies below its plot, so it
hides no curve whatever the data.  The validity limit is drawn wherever it lies on a plot's
crack axis (which its curves set: the limit moves no axis), and where it lies beyond, the
legend says so.  Elements carry ids (`beta`, `beta-held`, `validity-limit`, `validity-beyond`,
`residual-strength`, `limit-stress`, `a-crit`, `net-section-yield`; `plot-beta`,
`plot-strength` for the plot areas, `legend-beta`, `legend-strength`) for tools and tests."""

from __future__ import annotations

from typing import TYPE_CHECKING

from app.web import format as fmt
from app.web.catalogue import Curves
from app.web.charts import _CRITICAL, _INK, ImageFormat, _draw, _mm

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

_VALIDITY = "#805ad5"


def location_chart(name: str, curves: Curves, *, image_format: ImageFormat) -> bytes:
    """The location's beta(a) and, where it has a toughness, residual-strength chart."""
    return _draw(lambda: location_figure(name, curves), image_format)


def location_figure(name: str, curves: Curves) -> Figure:
    """The figure location_chart saves: two plots side by side, each legend below its own."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9, 4.4), layout="constrained")
    beta_axes, axes = figure.subplots(1, 2)
    _style(beta_axes, f"{name}: beta(a)", "beta", "beta")
    (line,) = beta_axes.plot(
        _mm(curves.beta_crack_m), curves.beta, color=_INK, linewidth=1.6, label="beta(a)"
    )
    line.set_gid("beta")
    beta_axes.plot(_mm(curves.beta_crack_m), curves.beta, "o", color=_INK, markersize=2.5)
    if curves.critical_crack_m > curves.beta_crack_m[-1]:
        # the march reads a table held at its last point: what it uses from there to a_crit
        (held,) = beta_axes.plot(
            [curves.beta_crack_m[-1] * 1000, curves.critical_crack_m * 1000],
            [curves.beta[-1], curves.beta[-1]],
            color=_INK,
            linestyle=":",
            linewidth=1.4,
            label="beta held at its limit value (as the march reads it)",
        )
        held.set_gid("beta-held")
    _validity_at(beta_axes, curves)
    _critical_at(beta_axes, curves.critical_crack_m)
    _legend_below(beta_axes, "beta")
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
    _style(axes, f"{name}: residual strength", "residual strength (MPa)", "strength")
    (strength,) = axes.plot(
        _mm(curves.strength_crack_m),
        curves.strength_mpa,
        color=_INK,
        linewidth=1.6,
        label="residual strength",
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
    _validity_at(axes, curves)
    _critical_at(axes, curves.critical_crack_m)
    axes.set_ylim(bottom=0)
    _legend_below(axes, "strength")
    return figure


def _style(axes: Axes, title: str, ylabel: str, plot: str) -> None:
    axes.patch.set_gid(f"plot-{plot}")
    axes.set_title(title, loc="left")
    axes.set_xlabel("crack length a (mm)")
    axes.set_ylabel(ylabel)
    axes.grid(True, linewidth=0.6)
    axes.spines[["top", "right"]].set_visible(False)


def _legend_below(axes: Axes, plot: str) -> None:
    """The legend under the plot and its axis label, outside the plot area: it hides no curve,
    wherever the data lie (constrained layout makes room for it)."""
    legend = axes.legend(
        loc="upper center",
        bbox_to_anchor=(0.5, -0.2),
        fontsize=8,
        frameon=False,
    )
    legend.set_gid(f"legend-{plot}")


def _validity_at(axes: Axes, curves: Curves) -> None:
    """The case's validity limit named with its reason: a line where it lies on the crack axis
    the plot's curves set (read before the line is drawn, so that a limit far past a_crit
    squeezes no curve), else said in the legend (a blank handle), as is a case without one."""
    if curves.validity_reason is None:
        return
    if curves.validity_limit_m is None:
        said = f"no validity limit on a: {curves.validity_reason}"
    else:
        limit_mm = curves.validity_limit_m * 1000
        said = f"validity limit {fmt.mm(curves.validity_limit_m)} mm, {curves.validity_reason}"
        low, high = axes.get_xlim()
        if low <= limit_mm <= high:
            line = axes.axvline(
                limit_mm, color=_VALIDITY, linestyle="-.", linewidth=1.2, label=said
            )
            line.set_gid("validity-limit")
            return
        said += ": beyond this axis"
    (blank,) = axes.plot([], [], " ", label=said)
    blank.set_gid("validity-beyond")


def _critical_at(axes: Axes, critical_crack_m: float) -> None:
    line = axes.axvline(
        critical_crack_m * 1000,
        color=_CRITICAL,
        linestyle="--",
        linewidth=1.2,
        label=f"a_crit {fmt.mm(critical_crack_m)} mm",
    )
    line.set_gid("a-crit")
