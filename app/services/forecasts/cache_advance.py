"""Advancing cached tails over their new flights instead of recomputing them.

Whoever stores flights brings its tails' rows up to date in the same transaction (catch_up,
called by app.services.forecasts.forecast_cache.recorded for an ingest and by app.services.forecasts.cache_fill for
a fill that read its history before flights arrived), so a row is never behind its tail's
flights once committed and readers (forecasts, the ranking) only read it: finding rows behind
at read time took a probe of every flight of the fleet per ranking (no index on flown_at; 57 %
of the server's samples under benchmarks/load.py).  An advance stores the new state with today's
risk and daily bands (one sampling, ~45 ms a tail and location), so no reader of today
samples anything.  With the bands left to the worker, a forecast of a tail just ingested
sampled them on the spot (up to 2 s under load: most of the slowest forecasts in
benchmarks/RESULTS.md's branch load4 runs), and the worker's later write of the row made every
API process compute that forecast and the ranking once more.  Tomorrow's risk (another ~45 ms,
read by nobody until midnight) is left to the worker's cache thread (app.worker: ranking.warm
for tomorrow), whose write keeps the row's stamp (cache_rows.store_risk), so no kept answer is
made anew for it.  A location other than the default one gets its risk alone (the same sampled
without bands): an aircraft's answer and the ranking read no more of it, and its own forecast
samples its bands on the spot, as the first forecast of a day does (ranking.warm stores risk
alone); left to the worker (fill_pending), they cost it ~0.23 s of CPU an ingest with four
locations to spare the API ~20 ms (benchmarks.ingest_cost).

A cached row (app.services.forecasts.forecast_cache) holds where its tail stands after its last recorded
flight (its origin): the crack under the fitted weights and under every posterior draw, each
draw with its own growth factor.  Flights appended after the origin move only that state, so
the row marches its stored cracks over the new flights (1-4 a day: microseconds) instead of the
tail's whole history under every draw and its growth posterior (0.5-1 s at 7,300 flights and
200 draws).  The Euler march is sequential, so the advanced crack is the recomputed one, up to
rounding and model.fleet_sampling's interpolation between marched growth factors
(tests/app/test_cache_advance.py).

A row cannot advance, and is recomputed from scratch, when a new flight lies at or before its
origin (the count of flights up to the origin moved) or an inspection lies after the first new
flight (that flight changes the inspection's flight count, so the tail's growth posterior; an
inspection between the origin and the new flights, the usual case, counts what it did).  Corrections,
deletions, repairs, new inspections and new initial cracks drop the row outright
(forecast_cache.invalidate).
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime

import torch
from sqlalchemy.orm import Session

from app.config import Settings
from app.services import models as model_service
from app.services.dates import days_ahead
from app.services.forecasts import advance_reads, cache_rows
from app.services.forecasts.cache_rows import CacheState
from app.services.forecasts.risk import fill_risk, stored_samples
from app.tables import DEFAULT_LOCATION_ID
from model.integrate import LoadHistory
from model.posterior import LocationPosterior


def catch_up(session: Session, rows: Sequence[CacheState], settings: Settings) -> int:
    """Bring these rows (any versions) up to their tails' flights inside the caller's
    transaction: advance those that can advance, drop the others (recomputed by their next
    reader), as do rows of another sample count.  The caller holds the rows (a write lock on
    SQLite, FOR UPDATE on PostgreSQL) and commits.  Returns the rows advanced."""
    size = 8 * settings.forecast_samples
    by_version: dict[int, list[CacheState]] = {}
    dropped: list[CacheState] = []
    for row in rows:
        if len(row.crack_samples_m or b"") == size:
            by_version.setdefault(row.model_version, []).append(row)
        else:
            dropped.append(row)
    advanced = 0
    reads = advance_reads.Reads()  # an aircraft's rows at its locations read its flights once
    for version, mine in sorted(by_version.items()):
        good, redo = advance_reads.advanceable(session, mine, reads)
        if good:
            posterior = model_service.load_posterior(session, version)
            advanced += advance(session, posterior, good, settings, reads)
        dropped.extend(row for row in mine if row.aircraft_id in set(redo))
    cache_rows.drop_states(session, dropped)
    return advanced


def fill_pending(session: Session, settings: Settings, *, limit: int = 8) -> int:
    """Sample what up to `limit` rows stored without bands lack (any version; an advance by an
    older release left them to this): the daily bands as of today and the risk as of tomorrow
    (risk.days_ahead), and store them where the row is still the state sampled (a forecast may
    have sampled its bands meanwhile: the same values).
    Run by the worker (app.worker), so the API's requests do not pay it.  Commits; returns the
    rows sampled."""
    rows = cache_rows.pending(session, settings, limit)  # snapshots: sampled and guarded
    session.rollback()  # the sampling below holds no transaction open
    by_version: dict[int, list[CacheState]] = {}
    for row in rows:
        by_version.setdefault(row.model_version, []).append(row)
    today, tomorrow = days_ahead(settings)
    horizon = settings.forecast_horizon_days
    for version, mine in sorted(by_version.items()):
        posterior = model_service.load_posterior(session, version)
        fill_risk(posterior, mine, horizon, settings, bands=True, as_of=today)
        fill_risk(posterior, mine, horizon, settings, bands=False, as_of=tomorrow)
        cache_rows.store_risk(session, mine, bands=True)
        session.commit()
    return len(rows)


def advance(
    session: Session,
    posterior: LocationPosterior,
    rows: Sequence[CacheState],
    settings: Settings,
    reads: advance_reads.Reads | None = None,
) -> int:
    """March these rows (one version, each advanceable) over their flights after the origin and
    store them with the default horizon's risk as of today, and the default location's daily
    bands (module docstring: left to the worker, they made a forecast sample on the spot);
    tomorrow's risk is the worker's (app.worker), whose write keeps the row's stamp
    (cache_rows.store_risk), as a forecast's store of another location's bands does.

    Each row is written only if nobody changed it since it was read (its origin and flight
    count), so two fillers never advance a row twice.  The caller commits.  Returns the number
    of rows stored.
    """
    if not rows:
        return 0
    reads = reads or advance_reads.Reads()
    new = [advance_reads.flights_after(session, row, posterior, reads) for row in rows]
    stress = LoadHistory.from_sequences(
        [torch.from_numpy(s) for _, s in new]
    ).stress_range_mpa  # (tails, flights)
    lengths = torch.tensor([len(s) for _, s in new])
    point_factor = _point_factors(rows)
    crack_now = torch.tensor([row.crack_length_m for row in rows], dtype=torch.float64)
    crack_now = posterior.advance_point(stress, lengths, crack_now, point_factor)
    stored_cracks, stored_factors = stored_samples(rows, settings.forecast_samples)
    cracks = posterior.advance_samples(
        torch.from_numpy(stored_cracks),
        None if stored_factors is None else torch.from_numpy(stored_factors),
        stress,
        lengths,
        settings.forecast_seed,
    )
    usage = [
        advance_reads.utilization(session, row, times, settings, posterior, reads)
        for row, (times, _) in zip(rows, new, strict=True)
    ]
    search_cap = [int(settings.critical_search_years * 365.25 * u.flights_per_day) for u in usage]
    to_critical = posterior.flights_to_critical(
        crack_now.tolist(),
        [u.recent_stress_mpa for u in usage],
        search_cap,
        growth_factor=None if point_factor is None else point_factor.tolist(),
    )
    now = datetime.now(UTC)
    advanced = []
    for i, row in enumerate(rows):
        times = new[i][0]
        origin_ns = int(times[-1])
        advanced.append(
            CacheState(
                aircraft_id=row.aircraft_id,
                location_id=row.location_id,
                model_version=row.model_version,
                computed_at=now,
                flights_flown=row.flights_flown + len(times),
                first_flown_at=row.first_flown_at,
                **cache_rows.standing(
                    origin_ns, float(crack_now[i]), cracks[:, i], to_critical[i], usage[i]
                ),
                risk={},
                bands=None,
                growth_samples=row.growth_samples,
                growth=row.growth,
            )
        )
    today, _ = days_ahead(settings)
    horizon = settings.forecast_horizon_days
    bands = rows[0].location_id == DEFAULT_LOCATION_ID  # one version: one location
    fill_risk(posterior, advanced, horizon, settings, bands=bands, as_of=today)
    if not bands:  # module docstring: sampled by the location's own forecast
        for state in advanced:
            state.bands = {}  # none of today's, yet not pending (cache_rows.pending)
    return sum(
        cache_rows.store_advanced(session, row, state)
        for row, state in zip(rows, advanced, strict=True)
    )


def _point_factors(rows: Sequence[CacheState]) -> torch.Tensor | None:
    """(tails,) each row's point growth factor (its posterior median), None without tracking."""
    if all(row.growth is None for row in rows):
        return None
    return torch.tensor(
        [1.0 if row.growth is None else float(row.growth["p50"]) for row in rows],
        dtype=torch.float64,
    )
