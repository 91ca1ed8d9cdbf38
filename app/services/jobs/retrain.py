"""Retrain: fit a new model version on every inspected aircraft, validate on held-out tails.

Held-out tails (about holdout_fraction of them, at least one when three or more are inspected)
are not trained on; their inspections give the validation |% error| metrics stored with the
version.  The new version is a candidate; it becomes active only when asked (the default) and
when it passes the promotion gate against the active version on the same held-out inspections
(app.services.jobs.promotion; the verdict is stored in its metrics["gate"] and the reason in the job
result).  The forecast cache is then filled for it, so forecasts keep coming from the previous
version until the switch.

Non-detections enter the censored loss of model.train (Observations.detected / detection_a50_m /
detection_a90_m; a hard threshold is a50 = a90).  Repairs split a tail's history into segments
with their own initial crack (app.services.records.segments), carried by the loads
(LoadHistory.initial_crack_m) into training.

The fit is `fleetpinn fit`'s, one recipe through the door (model.posterior.fit, today
model.kernel_choice.choose_kernel): Paris C and m learned first where
settings.learn_paris; individual aircraft tracking (model.tracking_fit.fit_tracked: the fleet
prior of per-tail growth factors, its spread by empirical Bayes, the sizing error from repeated
measurements; where the fleet scatters the shared model is refitted with each tail at its own
factor); then the Laplace posterior of the weights (model.uncertainty_fit.laplace_posterior, one
mode where tails scatter), stored with the version; the extrapolation beyond the measured
cracks (model.extrapolation) in its spec; where tails are measured more than once, the physics
alone instead where it predicts their later measurements better, and the drift of forecasts
beyond their posterior (model.path_variability), which the forecasts carry as `fleetpinn
predict`'s do.  The prior is stored in the version's metrics ("tracking") and in its model
file.  One difference from `fleetpinn fit`: where tails do not scatter, the final weights'
posterior keeps FLEETPINN_POSTERIOR_RESTARTS modes (9; `fit` keeps one, for a fit in seconds);
the refits behind the kernel choice and the drift take one in both (kernel_choice.path_fit).
"""

from __future__ import annotations

import uuid
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import torch
from sqlalchemy import exists, select
from sqlalchemy.orm import Session

from app.config import Settings
from app.services import audit
from app.services import models as model_service
from app.services.forecasts import cache_fill
from app.services.jobs import analysis_model, promotion, retrain_activation
from app.services.jobs import queue as jobs
from app.services.records import locations
from app.services.records.history import History, load_history
from app.services.records.stored_spectra import for_training
from app.tables import DEFAULT_LOCATION, DEFAULT_LOCATION_ID, Aircraft, Flight, Inspection
from model import posterior as door
from model.dynamo_import import skip_dynamo_import
from model.physics import ParisLaw


class NoTrainingData(ValueError):
    """No aircraft has both flights and a crack measurement."""


def _inspected_aircraft(session: Session, location_id: int = DEFAULT_LOCATION_ID) -> list[int]:
    """Aircraft with flights and an inspection at the location (the model's evidence)."""
    inspected = (Inspection.aircraft_id == Aircraft.id) & (Inspection.location_id == location_id)
    query = select(Aircraft.id).where(
        exists().where(inspected),
        exists().where(Flight.aircraft_id == Aircraft.id),
    )
    return list(session.scalars(query.order_by(Aircraft.id)))


def service_recipe(
    settings: Settings, params: dict[str, Any], physics: locations.Physics
) -> door.Recipe:
    """The retrain's recipe: `fleetpinn fit`'s (app.cli.offline.fit_recipe) with the settings'
    values, the location's physics (its law, whether C and m are learned, its sizing error) and
    the job's overrides (kernel, hidden, optimizer, lbfgs_iterations, epochs, seed); at the
    defaults the two differ in posterior_restarts alone (module docstring;
    tests/app/test_one_recipe.py)."""
    hidden_param = params.get("hidden")
    hidden = (
        tuple((int(u), str(a)) for u, a in hidden_param) if hidden_param else door.THESIS_MLPS[1]
    )
    return door.Recipe(
        kernel=params.get("kernel") or settings.kernel,
        law=physics.law,
        hidden=hidden,
        learn_paris=physics.learn_paris,
        sizing=physics.sizing,
        config=door.TrainConfig(
            optimizer=params.get("optimizer") or settings.optimizer,
            lbfgs_iterations=int(params.get("lbfgs_iterations") or settings.lbfgs_iterations),
            epochs=int(params.get("epochs") or settings.epochs),
            seed=settings.seed if params.get("seed") is None else int(params["seed"]),
        ),
        growth_sd=settings.growth_sd_prior,
        posterior_restarts=settings.posterior_restarts,
        extrapolation_sd=settings.extrapolation_slope_sd,
        growth_law=physics.growth_law,
    )


# a retrain's jobs per location share this key of their params (one value per retrain)
RETRAIN_GROUP = "retrain_group"


def enqueue_retrains(
    session: Session, params: dict[str, Any], *, actor: audit.Actor
) -> tuple[str, dict[str, str]]:
    """Queue one retrain job per location that some aircraft with flights carries (a
    catalogued location without inspections gets its analysis, app.services.jobs.analysis_model):
    the workers claim them in parallel, and each location's gate decides for it alone.  The
    default location has no analysis, so it is queued only where it has inspected aircraft,
    or where nothing else is (a fleet without inspections fails as it did, saying why).
    Returns the retrain's first job id (the default location's where it has one) and
    {location name: job id}."""
    named = sorted(
        location.name
        for location in locations.list_locations(session)
        if analysis_model.carried_with_flights(session, location.id)
        and (location.id != DEFAULT_LOCATION_ID or _inspected_aircraft(session))
    )
    if not named:
        named = [DEFAULT_LOCATION]
    several = len(named) > 1
    group = {RETRAIN_GROUP: uuid.uuid4().hex} if several else {}
    queued = {}
    for name in sorted(named, key=lambda n: n != DEFAULT_LOCATION):
        located = (
            {**params, **group}
            if name == DEFAULT_LOCATION
            else {**params, **group, "location": name}
        )
        queued[name] = jobs.enqueue(session, "retrain", located, actor=actor).id
    return next(iter(queued.values())), queued


def run_retrain(
    session: Session,
    *,
    job_id: str | None,
    params: dict[str, Any],
    settings: Settings,
    progress: Callable[..., None],
) -> dict[str, Any]:
    """Train, validate, store (and by default activate) a new version; returns the job result.

    params: optional overrides of Settings (kernel, hidden, optimizer, lbfgs_iterations, epochs,
    holdout_fraction, seed) and activate (default True).  progress(fraction, stage) hears the
    fraction done and the stage in words.  Raises NoTrainingData.

    A job runs again when its worker died (app.services.jobs.queue); if that attempt had already
    stored its version, this one fits nothing and acts on that version's stored gate verdict as
    the dead attempt would have (app.services.jobs.retrain_activation), so a job makes at most one
    version and a version that passed its gate is activated with or without a restart.
    """
    earlier = None if job_id is None else model_service.version_of_job(session, job_id)
    if earlier is not None:
        assert job_id is not None
        return retrain_activation.resume(
            session, earlier, job_id=job_id, params=params, settings=settings, progress=progress
        )
    progress(0.0, "loading the history")
    skip_dynamo_import()  # the fits' L-BFGS would import it: ~1.3 CPU s a worker process
    location = locations.get_location(session, params.get("location") or DEFAULT_LOCATION)
    aircraft_ids = _inspected_aircraft(session, location.id)
    if not aircraft_ids:
        if location.id != DEFAULT_LOCATION_ID and analysis_model.carried_with_flights(
            session, location.id
        ):
            return analysis_model.store_analysis(
                session, location, settings, job_id=job_id, params=params, progress=progress
            )
        where = "" if location.id == DEFAULT_LOCATION_ID else f" at location {location.name!r}"
        raise NoTrainingData(f"no aircraft has both flights and a crack measurement{where}")
    physics = locations.physics(location, settings)
    law: ParisLaw = physics.law
    read_after = cache_fill.audit_mark(session)  # what changes after this, the refill checks
    # kept for the retrain's next job in this process, at another location (app.services.records.history)
    history = load_history(
        session,
        aircraft_ids,
        initial_crack_m=law.initial_crack_m,
        location_id=location.id,
        keep_flights=True,
    )
    assert history is not None  # every aircraft chosen has flights
    history = for_training(session, history, physics.growth_law, law, physics.learn_paris)
    data, segments = history.data, history.segments
    loads = segments.loads
    progress(0.05, "fitting the model")

    recipe = service_recipe(settings, params, physics)
    kernel, hidden, config, seed = recipe.kernel, recipe.hidden, recipe.config, recipe.config.seed
    fraction = params.get("holdout_fraction")
    train, validation = door.holdout_split(
        len(data.tails), settings.holdout_fraction if fraction is None else float(fraction), seed
    )
    train_rows = np.flatnonzero(np.isin(segments.tail, train))
    train_loads, train_obs = door.select_rows(loads, segments.observations, train_rows)
    tails, row_tail = np.unique(segments.tail[train_rows], return_inverse=True)
    evidence = door.TailEvidence(train_loads, torch.from_numpy(row_tail), train_obs, len(tails))
    # the drift and the kernel choice read every inspected tail, held out or not
    path_evidence = door.TailEvidence(
        loads, torch.from_numpy(segments.tail), segments.observations, len(data.tails)
    )
    fitted = door.fit(
        recipe, evidence, lambda p: progress(0.05 + 0.6 * p), path_evidence=path_evidence
    )
    posterior, choice, result = fitted.posterior, fitted.choice, fitted.result
    prior = posterior.tracking
    assert prior is not None  # a fit tracks its tails
    weights = posterior.weights  # one mode where tails scatter (kernel_choice.Recipe)
    progress(0.82, "validating and storing")
    metrics: dict[str, Any] = {
        "train": posterior.errors(fitted.train_loads, train_obs),
        "tracking": prior.to_dict(),
        **posterior.physics_summary(learned=physics.learn_paris),
    }
    if choice:
        metrics["kernel_choice"] = choice
    if len(validation):
        val_rows = np.flatnonzero(np.isin(segments.tail, validation))
        val_loads, val_obs = door.select_rows(loads, segments.observations, val_rows)
        metrics["validation"] = posterior.errors(val_loads, val_obs)
        gate = promotion.evaluate(
            session,
            posterior,
            val_loads,
            val_obs,
            evaluated_on="validation",
            settings=settings,
            location_id=location.id,
            labels=_labels(history, val_rows),
        )
    else:
        metrics["validation"] = {"count": 0}
        # Nothing held out: both versions on the training inspections, at the fleet's rate.
        seen_loads, seen_obs = door.select_rows(loads, segments.observations, train_rows)
        gate = promotion.evaluate(
            session,
            posterior,
            seen_loads,
            seen_obs,
            evaluated_on="training",
            settings=settings,
            location_id=location.id,
            labels=_labels(history, train_rows),
        )
    if not gate.passed:
        gate = replace(gate, flagged=_flagged(session, [history.aircraft_ids[i] for i in train]))
    metrics["gate"] = gate.to_dict()
    training = {
        "kernel": kernel,
        "hidden": [list(layer) for layer in hidden],
        "optimizer": config.optimizer,
        "lbfgs_iterations": config.lbfgs_iterations,
        "epochs": config.epochs,
        "seed": seed,
        "final_loss": result.final_loss if result.loss_history else None,
        "seconds": result.seconds,
        "posterior": None
        if weights is None
        else {
            "kind": "laplace",
            "noise_sd": weights.noise_sd,
            "observations": weights.observations,
            "modes": len(weights.modes),
        },
        "train_tails": [data.tails[i] for i in train],
        "validation_tails": [data.tails[i] for i in validation],
        "observations": int(data.observations.aircraft.numel()),
        "non_detections": int(
            0 if data.observations.detected is None else (~data.observations.detected).sum()
        ),
        "repairs": int(len(segments.tail) - len(data.tails)),
    }
    version = model_service.store_version(
        session,
        posterior,
        training=training,
        metrics=metrics,
        job_id=job_id,
        location_id=location.id,
    )
    progress(0.88, "storing the version")
    # The history and the trained tails' growth posteriors are reused: the refill reads and
    # computes only what the fit did not (its flights read again cost ~10 s of 300 x 7,300;
    # benchmarks/tracking_service.py).
    known = cache_fill.Known(
        history, read_after, fitted.growth, None if fitted.growth is None else tails
    )
    outcome, reason = retrain_activation.activate_if_passed(
        session,
        version,
        gate,
        job_id=job_id,
        params=params,
        settings=settings,
        progress=progress,
        known=known,
    )
    return model_service.retrain_result(version, outcome, reason, metrics)


def _flagged(session: Session, aircraft_ids: list[int]) -> list[dict[str, Any]]:
    """The flagged inspections the candidate trained on (each far from its tail's forecast when
    stored): what may have moved it, named beside a refusal."""
    query = (
        select(Aircraft.tail, Inspection.inspection_id, Inspection.forecast_z)
        .join(Aircraft, Aircraft.id == Inspection.aircraft_id)
        .where(Inspection.flagged, Inspection.aircraft_id.in_(aircraft_ids))
        .order_by(Inspection.inspected_at)
    )
    return [
        {"inspection": f"{tail}/{inspection}", "z": z}
        for tail, inspection, z in session.execute(query)
    ]


def _labels(history: History, rows: np.ndarray) -> list[str]:
    """ "tail/inspection_id" of each observation of the segment rows `rows`, in the order
    select_rows keeps them (the inspections' own)."""
    kept = np.isin(history.segments.observations.aircraft.numpy(), rows)
    chosen = history.inspections[kept]
    return [f"{t}/{i}" for t, i in zip(chosen["tail"], chosen["inspection_id"], strict=True)]
