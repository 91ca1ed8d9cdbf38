"""The one door between the service and the statistics: a location's posterior.

The service asks three things of the statistics, as a state estimator and a predictor do
(NASA progpy's roles): `fit` gives a location's posterior from its evidence, `update` gives
tails' growth posteriors from their own inspections between retrains, and the predictive
methods give draws of each tail's crack and their readouts (risk, daily bands, flights to
critical).  This module is the only part of the statistics that app/ imports
(tests/test_imports.py); what lies behind it may change without the service knowing.

Behind the door today: the kernel choice's recipe (model.kernel_choice: calibration, the
tracked fit, the weights' Laplace posterior, the extrapolation beyond the measured cracks and
the forecasts' drift), the per-tail grid posterior (model.tracking_grid), and the sampled
forecasts (model.fleet_sampling, model.prognosis, model.path_drift).

A `LocationPosterior` is what a model version stores: the forward model (the hybrid cell and
its compiled march, model.hybrid), the posterior of its network's weights and the fleet prior
of the tails' growth factors; its model file (`to_bytes`, `from_bytes`) holds all three.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import Tensor

from model import artifacts
from model import forecast as fc
from model.evaluation import abs_percent_errors, holdout_split, select_rows
from model.extrapolation import DEFAULT_SLOPE_SD, Extrapolation
from model.fleet_sampling import TailRisk, crack_samples, daily_flights, sample_risk
from model.fleet_spread import spread_prior
from model.geometry_posterior import ShapePosterior
from model.hybrid import CrackGrowthModel, ModelSpec, kernel_names
from model.integrate import LoadHistory, Observations
from model.kernel_choice import Recipe, choose_kernel
from model.nets import ACTIVATIONS, THESIS_MLPS
from model.path_drift import PathDrift, latest_measured, wander
from model.physics import ParisLaw
from model.prognosis import LANES_PER_MARCH
from model.sample_advance import advance_crack_samples
from model.tracking import GrowthPosterior, SizingError, TailEvidence, TrackingPrior
from model.tracking_grid import growth_posterior
from model.train import OPTIMIZERS, FitResult, TrainConfig
from model.uncertainty import LaplacePosterior
from model.uncertainty_fit import DEFAULT_RESTARTS

__all__ = [
    "ACTIVATIONS",
    "DEFAULT_RESTARTS",
    "DEFAULT_SLOPE_SD",
    "LANES_PER_MARCH",
    "OPTIMIZERS",
    "THESIS_MLPS",
    "CrackGrowthModel",
    "Fitted",
    "GrowthPosterior",
    "LocationPosterior",
    "ModelSpec",
    "Recipe",
    "SizingError",
    "TailEvidence",
    "TailGrowth",
    "TailRisk",
    "TrackingPrior",
    "TrainConfig",
    "analysis",
    "daily_flights",
    "fit",
    "holdout_split",
    "kernel_names",
    "physics_alone",
    "select_rows",
]


@dataclass(frozen=True)
class TailGrowth:
    """Tails' growth posteriors as forecasts carry them: samples (samples, tails) of ln factor,
    each tail's from its own seed; point (tails,) the factor's median; quantiles (tails, 3)
    the factor's p05, p50, p95."""

    samples: Tensor
    point: Tensor
    quantiles: Tensor


@dataclass(frozen=True)
class LocationPosterior:
    """One location's fitted model: the forward model, the posterior of its network's weights
    (None: the physics alone, or a version stored without one) and the fleet prior of its
    tails' growth factors (None: a version stored before tracking, whose tails all keep the
    fleet's rate)."""

    model: CrackGrowthModel
    weights: LaplacePosterior | None
    tracking: TrackingPrior | None

    # ---- what the model file holds ------------------------------------------------------

    def to_bytes(self, metrics: dict[str, Any]) -> bytes:
        """The model file (model.artifacts): spec, weights, metrics and the weights' posterior;
        the tracking prior rides in metrics["tracking"]."""
        weights = None if self.weights is None else self.weights.to_dict()
        return artifacts.to_bytes(self.model, metrics, weights)

    def save(self, path: Path, metrics: dict[str, Any]) -> None:
        """Write the model file to path (`fleetpinn fit --out`)."""
        path.write_bytes(self.to_bytes(metrics))

    @classmethod
    def from_bytes(cls, data: bytes, metrics: dict[str, Any] | None = None) -> LocationPosterior:
        """Read a model file, its tracking prior from `metrics` where given (a version's stored
        metrics) else from the file's; raises ValueError for a damaged file or one of a newer
        format."""
        model, stored_metrics = artifacts.from_bytes(data)
        metrics = stored_metrics if metrics is None else metrics
        model.eval()
        stored = artifacts.posterior_from_bytes(data)
        tracking = metrics.get("tracking")
        return cls(
            model,
            None if stored is None else LaplacePosterior.from_dict(stored),
            None if tracking is None else TrackingPrior.from_dict(tracking),
        )

    def spec_dict(self) -> dict[str, Any]:
        return artifacts.spec_to_dict(self.model.spec)

    @property
    def law(self) -> ParisLaw:
        return self.model.spec.law

    @property
    def growth_law(self) -> str:
        return self.model.spec.growth_law

    def physics_summary(self, *, learned: bool) -> dict[str, Any]:
        """Paris C and m (learned or the settings'), the growth law and the extrapolation
        beyond the measured cracks (None for a model without one), as a version's metrics
        state them."""
        law, extrapolation = self.law, self.model.spec.extrapolation
        return {
            "paris": {"c": law.c, "m": law.m, "learned": learned},
            "growth_law": {"name": self.growth_law, "gamma": law.gamma},
            "extrapolation": None if extrapolation is None else extrapolation.to_dict(),
        }

    def errors(self, loads: LoadHistory, observations: Observations) -> dict[str, Any]:
        """|% error| of the fitted model at the measured inspections (model.evaluation)."""
        return abs_percent_errors(self.model, loads, observations)

    def at(self, loads: LoadHistory, observations: Observations) -> Tensor:
        """(observations,) crack in m under the fitted weights at each observation's flight."""
        with torch.no_grad():
            return self.model.at(loads, observations)

    def final_crack(self, loads: LoadHistory) -> Tensor:
        """(rows,) crack in m after each history under the fitted weights."""
        with torch.no_grad():
            return self.model.final_crack(loads)

    # ---- update: tails' growth posteriors from their own inspections --------------------

    def update(self, evidence: TailEvidence) -> GrowthPosterior:
        """Each tail's growth posterior given its own inspections and the fleet prior (the
        exact grid posterior, model.tracking_grid).  Requires a tracking prior."""
        assert self.tracking is not None, "a version without tracking has no growth posterior"
        return growth_posterior(self.model, evidence, self.tracking)

    def tail_growth(
        self, posterior: GrowthPosterior, samples: int, seeds: Sequence[int]
    ) -> TailGrowth:
        """`samples` draws of each tail's ln growth factor, tail i's from seeds[i] (so a tail's
        forecast does not depend on the tails drawn with it), with its median and quantiles."""
        draws = torch.stack(
            [
                posterior.select(torch.tensor([i])).sample(samples, seed)[:, 0]
                for i, seed in enumerate(seeds)
            ],
            dim=1,
        )
        quantiles = posterior.factor_quantiles((0.05, 0.5, 0.95))
        return TailGrowth(draws, self.point_growth(posterior), quantiles)

    def point_growth(self, posterior: GrowthPosterior) -> Tensor:
        """(tails,) the growth factor each tail's point values march at: its growth posterior's
        median, for a tail never inspected the fleet prior's (about exp(mu)), where the
        service's forecasts and `fleetpinn predict` alike take it."""
        return posterior.factor_quantiles((0.5,))[:, 0].clone()

    def drift_origins(self, loads: LoadHistory, observations: Observations) -> Tensor:
        """(rows,) where each history's drift beyond its posterior counts from: its latest
        measured crack, else the longer of its initial crack and the fleet's longest measured
        one (model.path_drift.latest_measured)."""
        law = self.law
        return latest_measured(
            loads, observations, law.initial_crack_m, self.model.spec.measured_up_to_m
        )

    # ---- predict: the crack now and ahead -----------------------------------------------

    def trajectory(self, loads: LoadHistory, initial_crack_m: Tensor | None = None) -> Tensor:
        """(rows, flights + 1) crack in m under the fitted weights, each row at its loads'
        growth factor, from initial_crack_m (default the loads' own initial crack)."""
        with torch.no_grad():
            if initial_crack_m is None:
                return self.model.trajectory(loads)
            return self.model.trajectory(loads, initial_crack_m)

    def advance_point(
        self,
        stress_mpa: Tensor,
        lengths: Tensor,
        crack_now_m: Tensor,
        growth_factor: Tensor | None,
    ) -> Tensor:
        """(tails,) crack in m under the fitted weights after each tail's `lengths` flights of
        stress_mpa (tails, flights), from crack_now_m, at its growth factor."""
        with torch.no_grad():
            trajectory = self.model(stress_mpa, lengths, crack_now_m, growth_factor)
        return trajectory[torch.arange(len(lengths)), lengths]

    def march_ahead(
        self, crack_now_m: Tensor, future_stress_mpa: Tensor, growth_factor: Tensor | None
    ) -> Tensor:
        """(tails, flights + 1) crack in m under the fitted weights over future loads."""
        return fc.march_ahead(self.model, crack_now_m, future_stress_mpa, growth_factor)

    def flights_to_critical(
        self,
        crack_now_m: Sequence[float],
        recent_stress_mpa: Sequence[np.ndarray],
        max_flights: Sequence[int],
        growth_factor: Sequence[float] | None = None,
    ) -> list[int | None]:
        """Flights until each tail's crack under the fitted weights reaches a_crit on its
        recent loads repeated, None past its cap (model.forecast.flights_to_critical)."""
        return fc.flights_to_critical(
            self.model,
            crack_now_m,
            recent_stress_mpa,
            self.law.critical_crack_m,
            max_flights,
            growth_factor=growth_factor,
        )

    def crack_now(
        self,
        loads: LoadHistory,
        initial_crack_m: Tensor,
        *,
        samples: int,
        seed: int,
        log_growth: Tensor | None = None,
    ) -> Tensor:
        """(samples, tails) crack in m after each history, sample k under its own weights,
        its own growth factor exp(log_growth[k]) and its own slope beyond the measured cracks
        (model.fleet_sampling.crack_samples)."""
        return crack_samples(
            self.model,
            self.weights,
            loads,
            initial_crack_m,
            samples=samples,
            seed=seed,
            growth_factor=None if log_growth is None else torch.exp(log_growth),
        )

    def advance_samples(
        self,
        crack_m: Tensor,
        growth_factor: Tensor | None,
        stress_mpa: Tensor,
        lengths: Tensor,
        seed: int,
    ) -> Tensor:
        """(samples, tails) crack after the flights stress_mpa (tails, flights), sample k from
        its own stored crack crack_m[k] under its own weights (crack_now's draws for the same
        seed), growth factor growth_factor[k] and slope beyond the measured cracks (the stored
        cracks are under it: marched from where they stand without it, then mapped back).  The
        Euler march is sequential, so this is crack_now over the whole history."""
        return advance_crack_samples(
            self.model, self.weights, crack_m, growth_factor, stress_mpa, lengths, seed
        )

    def risk(
        self,
        crack_now_m: np.ndarray,
        futures: Sequence[fc.FutureLoads],
        rates: Sequence[float],
        horizon_days: int,
        *,
        samples: int,
        seed: int,
        bands: bool,
        growth_factor: np.ndarray | None,
        marks: Sequence[Sequence[int]],
        drift_from_m: Sequence[float],
        tail_seeds: Sequence[int],
        detectable_crack_m: float | None,
    ) -> list[TailRisk]:
        """Each tail's sampled risk over horizon_days (model.fleet_sampling.sample_risk), sample
        k from crack_now_m[k, i] (samples, tails) at growth factor growth_factor[k, i], its
        future drawn from futures[i] at rates[i] flights a day; every point of a path drifts
        beyond drift_from_m[i] (inf: not at all) by the version's path sd, each tail's noise
        from tail_seeds[i] (model.path_drift.PathDrift)."""
        drift = None
        if self.model.spec.path_sd > 0:
            drift = PathDrift.drawn(
                self.model.spec.path_sd,
                torch.tensor(list(drift_from_m), dtype=torch.float64),
                samples,
                list(tail_seeds),
            )
        return sample_risk(
            self.model,
            self.weights,
            crack_now_m,
            futures,
            rates,
            horizon_days,
            samples=samples,
            seed=seed,
            bands=bands,
            growth_factor=growth_factor,
            marks=marks,
            drift=drift,
            detectable_crack_m=detectable_crack_m,
        )

    def wander(self, crack_m: Tensor, since_m: Tensor) -> Tensor:
        """Crack samples moved by the version's drift beyond since_m (model.path_drift.wander),
        as `fleetpinn predict` widens the crack now."""
        path_sd = 0.0 if self.tracking is None else self.tracking.path_sd
        return wander(crack_m, since_m, path_sd)


@dataclass(frozen=True)
class Fitted:
    """What `fit` gives: the location's posterior; the record of its kernel choice ({} where
    nothing was compared); the record of the fit of the weights; the histories it trained on
    (each tail at its fitted factor); and the trained tails' growth posteriors, where the fit
    computed them on the evidence as `update` would (None: `update` computes them)."""

    posterior: LocationPosterior
    choice: dict[str, Any]
    result: FitResult
    train_loads: LoadHistory
    growth: GrowthPosterior | None


def fit(
    recipe: Recipe,
    evidence: TailEvidence,
    progress: Callable[[float], None] | None = None,
    path_evidence: TailEvidence | None = None,
) -> Fitted:
    """A location's posterior from its evidence (model.kernel_choice.choose_kernel: the recipe's
    model, or the physics alone where it predicts held-out later measurements better).
    path_evidence: what the leave-future-out refits read (default the evidence)."""
    chosen, choice = choose_kernel(recipe, evidence, progress, path_evidence=path_evidence)
    fitted, tracked = chosen.fitted, chosen.tracked
    growth = tracked.posterior if fitted.prior.scatters else None
    return Fitted(
        LocationPosterior(fitted.model, fitted.weights, fitted.prior),
        choice,
        tracked.result,
        tracked.loads,
        growth,
    )


def physics_alone(law: ParisLaw | None = None) -> LocationPosterior:
    """The law's physics alone (the default law where none is given), nothing fitted."""
    spec = ModelSpec(kernel="physics") if law is None else ModelSpec(kernel="physics", law=law)
    return LocationPosterior(CrackGrowthModel(spec), None, None)


def analysis(
    law: ParisLaw,
    growth_law: str,
    *,
    slope_sd: float,
    growth_sd: float,
    sizing: SizingError,
) -> LocationPosterior:
    """A location's posterior before any inspection: the physics alone (its table of F,
    where it has one), nothing fitted, its tails drawn from the fleet spread's prior
    (model.fleet_spread.spread_prior; growth_sd is the spread an inspected tail would be held
    to), and its geometry factor's trend unknown from a0 on with prior sd slope_sd
    (model.extrapolation)."""
    extrapolation = Extrapolation.under(
        law, law.initial_crack_m, ShapePosterior.prior(law, slope_sd)
    )
    spec = ModelSpec(kernel="physics", law=law, growth_law=growth_law, extrapolation=extrapolation)
    tracking = TrackingPrior(growth_sd, sizing, uninspected_spread=spread_prior())
    return LocationPosterior(CrackGrowthModel(spec), None, tracking)
