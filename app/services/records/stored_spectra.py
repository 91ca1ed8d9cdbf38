"""A history's stored cycles (spectrum_blocks) as training and forecasting evidence.

A flight's stored stress_range_mpa is its cycles' damage-equivalent range under the law
configured when it was ingested (app.services.records.spectra); a law learned later (Walker's gamma, or
m) weighs the cycles differently, and a range reduced under one gamma carries no load ratio to
learn another from.  So a retrain under such a law, and a forecast of its version, read the
cycles themselves: each flight's loads become its stored cycles (scaled to the location, as its
range is), a flight recorded as one range one cycle of that range at R = 0 (which every law
reduces to the range itself), all reduced under the given law as `fleetpinn fit` reads a cycle
file (model.spectrum_files.with_cycles).  A history none of whose flights recorded cycles comes
back as it was, so single-range fleets train and forecast exactly as before.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import torch
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.services.records.history import History
from app.services.records.locations import location_by_id, scaled
from app.services.records.segments import split_at_repairs
from app.services.records.spectra import cycles_of
from app.storage import chunks
from app.tables import DEFAULT_LOCATION_ID, Flight, FlightBlock, SpectrumBlock
from model.cycle_counting import FlightCycles, spectrum_of
from model.growth_laws import GROWTH_LAWS, CycleSpectrum, GrowthConstants
from model.integrate import LoadHistory
from model.physics import ParisLaw

CHANNELS = 3  # stress_range_mpa, load_ratio, count (app.tables.SpectrumBlock.cycles)


def for_training(
    session: Session, history: History, growth_law: str, law: ParisLaw, learn: bool
) -> History:
    """The retrain's evidence: `history` with its stored cycles where the fit weighs them
    (a law with a load-ratio exponent, or C and m learned: m reweighs a flight's cycles too),
    reduced under the law it starts from; else `history` itself."""
    if not (GROWTH_LAWS[growth_law].uses_gamma or learn):
        return history
    return with_stored_cycles(session, history, growth_law, law.constants)


def with_stored_cycles(
    session: Session, history: History, growth_law: str, constants: GrowthConstants
) -> History:
    """`history` whose loads (data and segments) carry every flight's cycles, each flight's
    range reduced under the law (module docstring); data.flights' stress_range_mpa becomes
    that range too, so the recent usage forecasts resample weighs the future's load ratios as
    the law does.  A history that carries cycles already is only re-reduced (no query)."""
    data = history.data
    loads = data.loads
    if loads.cycles is None:
        cycles = _stored_cycles(session, history)
        if cycles is None:
            return history
        loads = LoadHistory.from_cycles(cycles, loads.lengths, growth_law, constants)
    else:
        loads = loads.for_law(growth_law, constants)
    flights = data.flights.copy()
    aircraft = flights["aircraft"].to_numpy()
    position = flights["flight"].to_numpy() - 1
    flights["stress_range_mpa"] = loads.stress_range_mpa.numpy()[aircraft, position]
    data = replace(data, loads=loads, flights=flights)
    old = history.segments
    first_segment = np.concatenate(([0], old.last[:-1] + 1))
    initial = old.loads.initial_or(0.0)[torch.from_numpy(first_segment)]
    return replace(
        history, data=data, segments=split_at_repairs(data, history.inspections, initial)
    )


def reduced_ranges(
    ranges_mpa: np.ndarray,
    blobs: list[bytes | None],
    growth_law: str,
    constants: GrowthConstants,
) -> np.ndarray:
    """(flights,) each flight's range as stored, or where it stored cycles (`blobs`, a
    flight's FlightCycles.packed bytes or None, app.services.records.spectra.blobs_of) their
    damage-equivalent range under the law: what a cached
    forecast advances over and resamples its future from, as the fill reads the history."""
    recorded = [i for i, blob in enumerate(blobs) if blob is not None]
    if not recorded:
        return ranges_mpa
    flights = [FlightCycles.unpacked(blobs[i]) for i in recorded]  # type: ignore[arg-type]
    out = np.array(ranges_mpa, dtype=np.float64)
    law = GROWTH_LAWS[growth_law]
    out[recorded] = law.equivalent_range(spectrum_of(flights), constants)[0].numpy()
    return out


def _stored_cycles(session: Session, history: History) -> CycleSpectrum | None:
    """(tails, flights, cycles) every flight's cycles in the history's order: the stored ones,
    or one cycle (range, R = 0, count 1) of its range; None where no flight stored any."""
    if session.scalar(select(SpectrumBlock.id).limit(1)) is None:
        return None  # a fleet that never sent cycles pays one probe, not a query per tail
    index = {aircraft: i for i, aircraft in enumerate(history.aircraft_ids)}
    parts = []
    for part in chunks(list(history.aircraft_ids)):
        rows = session.execute(
            select(
                Flight.aircraft_id,
                Flight.flight_id,
                FlightBlock.spectrum_block_id,
                FlightBlock.spectrum_index,
            )
            .select_from(FlightBlock)
            .join(Flight, Flight.id == FlightBlock.flight_pk)
            .where(Flight.aircraft_id.in_(part))
        ).all()
        if rows:
            parts.append(pd.DataFrame(rows, columns=["aircraft_id", "flight_id", "block_id", "at"]))
    if not parts:
        return None
    stored = pd.concat(parts, ignore_index=True)
    stored["aircraft"] = stored["aircraft_id"].map(index)
    flights = history.data.flights
    keyed = flights[["aircraft", "flight_id", "flight"]].reset_index(names="row")
    found = stored.merge(keyed, on=["aircraft", "flight_id"], how="inner")
    cycles = cycles_of(session, found["block_id"].to_numpy(), found["at"].to_numpy())
    sizes = np.diff(cycles.starts)
    table = cycles.table

    tails, steps = history.data.loads.stress_range_mpa.shape
    width = max(int(sizes.max(initial=1)), 1)
    padded = np.zeros((CHANNELS, tails, steps, width))
    # a flight recorded as one range: one cycle of it (its range here is the location's already)
    aircraft = flights["aircraft"].to_numpy()
    position = flights["flight"].to_numpy() - 1
    padded[0, aircraft, position, 0] = flights["stress_range_mpa"].to_numpy(np.float64)
    padded[2, aircraft, position, 0] = 1.0
    # a flight recorded as cycles: its cycles, scaled as the location scales its range
    recorded = found["row"].to_numpy()
    factor = _location_factor(session, history, flights.iloc[recorded])
    flight_of_cycle = np.repeat(np.arange(len(found)), sizes)
    cycle = np.arange(len(table)) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    at_tail = found["aircraft"].to_numpy()[flight_of_cycle]
    at_flight = found["flight"].to_numpy()[flight_of_cycle] - 1
    padded[:, aircraft[recorded], position[recorded], 0] = 0.0
    padded[0, at_tail, at_flight, cycle] = table[:, 0] * factor[flight_of_cycle]
    padded[1, at_tail, at_flight, cycle] = table[:, 1]
    padded[2, at_tail, at_flight, cycle] = table[:, 2]
    return CycleSpectrum(*(torch.from_numpy(padded[c]) for c in range(CHANNELS)))


def _location_factor(session: Session, history: History, flights: pd.DataFrame) -> np.ndarray:
    """(flights,) the factor the history's location scales these flights' ranges by (1 at the
    default location; app.services.records.locations.local_stress)."""
    ones = np.ones(len(flights))
    if history.location_id == DEFAULT_LOCATION_ID:
        return ones
    missions = flights["mission"] if "mission" in flights.columns else None
    return scaled(ones, missions, location_by_id(session, history.location_id))
