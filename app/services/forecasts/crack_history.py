"""A tail's crack over its recorded flights, as the active model estimates it: the curve its
forecast continues.

Each segment of the tail's history (app.services.records.segments: a repair restarts the crack) marches
from its own initial crack under the fitted weights, at the tail's median growth factor where the
version tracks tails (the point value the forecast cache marches), so the curve ends at the
forecast's crack_length_m.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from datetime import datetime

import numpy as np
import torch
from sqlalchemy.orm import Session

from app.config import Settings
from app.services import models as model_service
from app.services.dates import from_ns, ns
from app.services.forecasts.cache_rows import Subject
from app.services.forecasts.forecast_cache import cached_state
from app.services.records import locations
from app.services.records.aircraft import find_aircraft
from app.services.records.history import load_history

# Points of the curve at most: every k-th flight (and the last), enough for a chart.
MAX_POINTS = 800


@dataclass(frozen=True)
class CrackHistory:
    """dates: (points,) after which flight; crack_m: (points,) estimated crack in m; flights:
    (points,) how many flights were flown by then (a coupon's blocks, a test's cycles / block);
    flown_at_ns: (flights,) every recorded flight's time, for flights_before."""

    dates: list[datetime]
    crack_m: list[float]
    flights: list[int] = field(default_factory=list)
    flown_at_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def flights_before(self, moment: datetime) -> int:
        """Recorded flights flown before `moment` (what an inspection then had seen)."""
        return int(np.searchsorted(self.flown_at_ns, ns(moment), side="left"))

    def last_flight_before(self, moment: datetime) -> datetime | None:
        """The last recorded flight before `moment` (None: none): where an inspection's
        finding was compared with the estimate (app.services.forecasts.assessment)."""
        flown = self.flights_before(moment)
        return from_ns(int(self.flown_at_ns[flown - 1])) if flown else None


def crack_history(
    session: Session,
    tail: str,
    settings: Settings,
    *,
    max_points: int = MAX_POINTS,
    location: str | None = None,
) -> CrackHistory:
    """The tail's estimated crack after its recorded flights (at most max_points of them, the
    last one always) at the location (default: the default one) under its active version.
    Raises NotFoundError (unknown tail or location) or ConflictError (no active model, no
    flights)."""
    if max_points < 2:
        raise ValueError(f"max_points must be >= 2, got {max_points}")
    aircraft = find_aircraft(session, tail)
    location_id = locations.location_id(session, location)
    version = model_service.require_active_version(session, location_id)
    subject = Subject(aircraft.id, location_id)
    state = cached_state(session, subject, version, settings)  # ConflictError: no flights
    posterior = model_service.load_posterior(session, version)
    law = posterior.law
    history = load_history(
        session,
        [aircraft.id],
        initial_crack_m=law.initial_crack_m,
        location_id=location_id,
    )
    assert history is not None  # cached_state found flights
    segments = history.segments
    factor = None if state.growth is None else float(state.growth["p50"])
    loads = segments.loads
    if factor is not None:
        loads = replace(
            loads, growth_factor=torch.full((len(segments.tail),), factor, dtype=torch.float64)
        )
    trajectory = posterior.trajectory(loads, loads.initial_or(law.initial_crack_m))
    times = history.data.flights["flown_at"].dt.tz_convert(None).to_numpy("datetime64[ns]")
    crack = np.empty(len(times))  # (flights,) crack after each flight
    for s, (start, length) in enumerate(zip(segments.start, loads.lengths.tolist(), strict=True)):
        crack[start : start + length] = trajectory[s, 1 : length + 1].numpy()
    step = max(1, -(-len(times) // max_points))
    keep = np.unique(np.append(np.arange(0, len(times), step), len(times) - 1))
    return CrackHistory(
        dates=[from_ns(int(t)) for t in times[keep].view("int64")],
        crack_m=crack[keep].tolist(),
        flights=(keep + 1).tolist(),
        flown_at_ns=times.view("int64"),
    )


def crossed_at(history: CrackHistory, critical_crack_m: float) -> datetime | None:
    """The first recorded flight after which the estimated crack reached a_crit, where the
    curve reaches it (None: it never did): the date a tail past critical during its recorded
    flights crossed, rather than its last flight."""
    reached = np.flatnonzero(np.asarray(history.crack_m) >= critical_crack_m)
    return history.dates[int(reached[0])] if len(reached) else None
