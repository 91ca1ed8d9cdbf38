"""Fitting a tracked model the way it will be used, and whether its network earns its place.

`Recipe` is how a model is fitted (kernel, law, whether C and m are learned), so that it can be
fitted again on part of the data: model.path_variability refits it on the earlier part of each
tail's measurements to see how far forecasts drift from the later ones.

Why a choice of kernel.  With a few inspections of a few tails the residual kernel fits their
noise and bends the extrapolation: on Hudak's alloy-A specimens (benchmarks/real_data.py) it
erred more than the per-specimen Paris fits where the calibrated physics did not.  With many
inspections of a fleet whose physics lacks a geometry factor (the thesis's), the network is
what makes the forecast.  Which holds is a property of the data, so the data decide: the one
whose later measurements, predicted from the earlier ones, are the more likely is kept.  Where
no tail is measured twice, nothing can be held out and the recipe's kernel stands; nor where no
tail keeps two measured cracks before its held-out ones (two rounds of inspections): refitted on
one inspection a tail, the network cannot learn from a tail's growth between inspections, which
is what the full fit learns it from, so the physics won by construction (benchmarks/locations.py:
every location, the largest cracks 20-38 % short at the wing splice).

Why the physics where no tail (or too few to hold any out: path_variability.MIN_HELD_OUT) is
measured twice and tails scatter.  Each tail then shows one crack, and what the fleet's cracks tell is their spread at the times measured; the kernel's
shape over crack length and the fleet's spread in rate both shape it, and the network traded one
for the other.  On a fleet whose true geometry factor is a constant 1.08, inspected once at year
2 (benchmarks/extrapolation.py flat-early), it learned a correction falling 20 % from 5 to 13 mm
(the fleet's mean rate read 1.32 and its spread 0.30 against 0.25), held it beyond, and the 28
inspected tails that reached a_crit within the year got P(critical) >= 0.5 for 7 (the physics
with the fleet's learned mean rate: 26; the oracle 26).  Nothing can be held out to tell which
shape holds, so the physics stands, assuming no shape the data cannot check: the fleet's mean
rate carries a constant discrepancy, and the trend beyond the measured cracks
(model.extrapolation) the unknown one.  Where tails do not scatter (the thesis's fleet) the
spread is not free to trade, and the network learns the shape from how the tails' cracks
differ with their loads.

The drift where nothing is held out and tails scatter.  Forecasts then follow a shape nobody
checked from each tail's own measured crack on, and no later measurement says how far they
drift (path_variability), so the drift is a prior, UNTOLD_PATH_SD, not zero: at zero, a fleet
whose geometry factor accelerates towards a panel's edge, inspected once at year 4
(benchmarks/extrapolation.py secant-once, secant-sparse), gave tails that reached a_crit
within the year P(critical) < 0.05 and bands that held 60-89 % of the inspected tails.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

from model.extrapolation import DEFAULT_SLOPE_SD, Extrapolation, fitted_extrapolation
from model.nets import THESIS_MLPS
from model.paris_calibration import calibrate_law
from model.path_variability import FittedForTracking, PathFit, earlier_repeats, estimate_path_sd
from model.physics import ParisLaw
from model.tracking import SizingError, TailEvidence
from model.tracking_fit import TrackedFit, fit_tracked
from model.train import FitResult, TrainConfig, build_crack_model
from model.uncertainty_fit import laplace_posterior

# why the physics was kept where nothing can be held out and tails scatter (module docstring)
SHAPE_UNTOLD = (
    "too few tails are measured twice to hold any measurement out, and tails scatter: the "
    "correction's shape over crack length trades against the fleet's spread, and nothing can "
    "tell them apart"
)
# the forecasts' drift (path_sd) where nothing is held out to measure it and tails scatter
# (module docstring): the size the leave-future-out refits measure on fleets inspected twice
# whose geometry factor rises beyond the measured cracks (0.4-1.4; a constant one 0.1), chosen on
# fleets inspected once whose factor accelerates, is flat and falls off (benchmarks/RESULTS.md)
UNTOLD_PATH_SD = 0.5
# why the kernels were not compared where no tail's earlier record holds two measured cracks
UNCOMPARABLE = (
    "no tail keeps two measured cracks before the held-out ones: refitted on one inspection a "
    "tail, the network cannot learn what the full fit learns from each tail's growth between "
    "its inspections, so the comparison would favour the physics by construction"
)


# growth laws whose rate is a flight's damage times a function of the crack (NASGRO's threshold
# and closure are not): the shape's likelihood, in the flights' summed damage, is exact for them,
# and only they carry the learned shape inside the march
SEPARABLE = ("paris", "walker")


@dataclass(frozen=True)
class Recipe:
    """How a tracked model is fitted: kernel and network, the law it starts from, whether C and
    m are learned first (model.paris_calibration), the assumed sizing error, the fit's config,
    the fleet spread assumed while too few tails are inspected to learn it, the prior sd of the
    geometry factor's trend beyond the measured cracks (model.extrapolation), and the modes of
    the weights' posterior where tails do not scatter (where they do, one: the fit's own, sampled
    with each tail's growth posterior; it is what widens the bands where the kernel
    extrapolates: benchmarks/tracking.py seed 1, p95 error 79.7 % -> 65.5 %, and its 12 tails
    that reach a_crit flagged, benchmarks/RESULTS.md), and the forecasts' drift where nothing can
    be held out to measure it and tails scatter (UNTOLD_PATH_SD)."""

    kernel: str = "physics"
    law: ParisLaw = field(default_factory=ParisLaw)
    hidden: tuple[tuple[int, str], ...] = THESIS_MLPS[1]
    learn_paris: bool = False
    sizing: SizingError = field(default_factory=SizingError)
    config: TrainConfig = field(default_factory=TrainConfig)
    growth_sd: float = 0.0
    posterior_restarts: int = 1
    extrapolation_sd: float = DEFAULT_SLOPE_SD
    growth_law: str = "paris"
    untold_path_sd: float = UNTOLD_PATH_SD

    def fit(
        self, evidence: TailEvidence, progress: Callable[[float], None] | None = None
    ) -> tuple[FittedForTracking, TrackedFit]:
        """Calibrate (if asked), build over the evidence's measured crack range, fit with
        tracking, then the weights' posterior with each tail at its factor, and the
        extrapolation beyond the measured cracks (into the model's spec)."""
        law = self.law
        if self.learn_paris:
            law = calibrate_law(evidence, law, self.sizing, growth_law=self.growth_law)[0]
        model = build_crack_model(
            evidence.loads,
            kernel=self.kernel,
            hidden=self.hidden,
            law=law,
            seed=self.config.seed,
            observations=evidence.observations,
            growth_law=self.growth_law,
        )
        tracked = fit_tracked(
            model, evidence, self.sizing, self.config, growth_sd=self.growth_sd, progress=progress
        )
        restarts = 1 if tracked.prior.scatters else self.posterior_restarts
        weights = (
            laplace_posterior(model, tracked.loads, evidence.observations, restarts=restarts)
            if model.network_parameters()
            else None
        )
        extrapolation = fitted_extrapolation(
            model.spec.law,
            evidence.observations,
            model.loads_for(evidence.loads),
            tracked.prior.sizing,
            tracked.prior.growth_sd,
            self.extrapolation_sd,
            evidence.row_tail,
        )
        if (
            self.kernel == "physics"
            and self.growth_law in SEPARABLE
            and law.geometry_table
            != (
                corrected := extrapolation.shape.corrected_law(law, extrapolation.seen_crack_m)
            ).geometry_table
        ):
            # the physics with the geometry factor's learned correction inside, its tails tracked
            # under it
            model = build_crack_model(
                evidence.loads, kernel="physics", law=corrected, growth_law=self.growth_law
            )
            tracked = fit_tracked(
                model, evidence, self.sizing, self.config, growth_sd=self.growth_sd
            )
            extrapolation = Extrapolation.under(
                corrected, extrapolation.seen_crack_m, extrapolation.shape
            )
        model.spec = replace(model.spec, extrapolation=extrapolation)
        growth = tracked.posterior if tracked.fresh else None
        return FittedForTracking(model, weights, tracked.prior, growth), tracked


@dataclass(frozen=True)
class TrackedModel:
    """A fitted model with all its tracking (its prior carries path_sd), its tracked fit (the
    tails' growth posteriors, the record of the fit of the weights) and its leave-future-out
    record."""

    fitted: FittedForTracking
    tracked: TrackedFit
    path: PathFit

    @property
    def result(self) -> FitResult:
        return self.tracked.result


def path_fit(recipe: Recipe, evidence: TailEvidence) -> PathFit:
    """The recipe's leave-future-out record on the evidence: refitted on the earlier part of
    each tail's record, its later measurements predicted (model.path_variability).  The refits
    take one mode of the weights' posterior whatever the recipe's (what they estimate is the
    drift of the fit, not its modes' spread; nine modes made the residual kernel's held-out
    likelihood a different number in the service than in `fleetpinn fit`)."""
    refit = replace(recipe, posterior_restarts=1)
    return estimate_path_sd(
        lambda earlier: refit.fit(earlier)[0], evidence, recipe.law.critical_crack_m
    )


def with_path(fitted: FittedForTracking, tracked: TrackedFit, path: PathFit) -> TrackedModel:
    """A model fitted on all the evidence, its forecasts' drift (path_sd) from `path`
    (path_fit's record)."""
    fitted.model.spec = replace(fitted.model.spec, path_sd=path.path_sd)
    prior = replace(fitted.prior, path_sd=path.path_sd)
    if path.held_out_log_likelihood is not None:
        prior = replace(prior, estimated=(*prior.estimated, "path_sd"))
    return TrackedModel(replace(fitted, prior=prior), replace(tracked, prior=prior), path)


def measured_sizing(recipe: Recipe, fitted: FittedForTracking) -> Recipe:
    """The recipe whose assumed sizing error is the one measured on all the evidence, for the
    leave-future-out refits: a refit keeping one inspection a tail cannot estimate it, and the
    assumed default (5 %) then swamped the drift (Hudak's alloy-A to 30,000 cycles: predictive
    sd 5 % against errors of 2 %, so the drift read 0 and the bands held 85 %).  The sizing error
    is the inspection method's, the same before and after a forecast's origin."""
    return replace(recipe, sizing=fitted.prior.sizing)


def choose_kernel(
    recipe: Recipe,
    evidence: TailEvidence,
    progress: Callable[[float], None] | None = None,
    path_evidence: TailEvidence | None = None,
) -> tuple[TrackedModel, dict[str, Any]]:
    """The recipe's model, or the physics alone where it predicts the held-out later
    measurements better, or where nothing can be held out and tails scatter (module
    docstring); and the record of the choice.  `fleetpinn fit`
    and the service's retrain both fit this way.

    The recipe's kernel is fitted on all the evidence first: the refits assume the sizing error
    it measured (measured_sizing).  The physics is fitted on all of it only where it is chosen
    (a retrain of 300 tails inspected twice: 97 s when both always were, the goal 60 s).
    path_evidence: what those refits read (default the evidence;
    the retrain fits on its training tails but reads the drift from every inspected one, since
    its holdout is for the promotion gate and the refits hold out the future of their own)."""
    held_out = path_evidence or evidence
    fitted, tracked = recipe.fit(evidence, progress)
    refits = measured_sizing(recipe, fitted)
    path = path_fit(refits, held_out)
    if path.held_out_log_likelihood is None and tracked.prior.scatters:
        path = PathFit(recipe.untold_path_sd, None)  # a prior: nothing measured it
    if recipe.kernel == "physics":
        return with_path(fitted, tracked, path), {}
    if path.held_out_log_likelihood is None:
        if not tracked.prior.scatters:
            return with_path(fitted, tracked, path), {}
        physics = replace(recipe, kernel="physics").fit(evidence)
        return with_path(*physics, path), {"chosen": "physics", "not_compared": SHAPE_UNTOLD}
    if not earlier_repeats(held_out, recipe.law.critical_crack_m):
        record: dict[str, Any] = {"chosen": recipe.kernel, "not_compared": UNCOMPARABLE}
        return with_path(fitted, tracked, path), record
    physics_path = path_fit(replace(refits, kernel="physics"), held_out)
    assert physics_path.held_out_log_likelihood is not None
    better = physics_path.held_out_log_likelihood > path.held_out_log_likelihood
    record = {
        "held_out_log_likelihood": {
            recipe.kernel: path.held_out_log_likelihood,
            "physics": physics_path.held_out_log_likelihood,
        },
        "chosen": "physics" if better else recipe.kernel,
    }
    if better:
        physics = replace(recipe, kernel="physics").fit(evidence)  # progress ran with the first
        return with_path(*physics, physics_path), record
    return with_path(fitted, tracked, path), record
