"""Flights sent as cycles or as a stress history: counted, reduced to one range, stored as sent.

A flight's loads come in one of three forms (app.schemas.FlightIn): one stress range, its
cycles, or a stress history counted into cycles by rainflow (model.cycle_counting).  The
flight's stress_range_mpa becomes its cycles' damage-equivalent range under the configured law
(settings growth_law and its constants, model.growth_laws), so every forecast and retrain reads
flights as before, and the cycles (with the history, where one was sent) are stored in
spectrum_blocks in the ingest's own transaction, for a later law to be refitted to them: one row
per tail and upload holding its flights' cycles back to back, and a flight_blocks row per flight
naming its block and its place in it (app.tables.SpectrumBlock, FlightBlock; deleted with its
flight).  Every reader goes from the stored flights through flight_blocks to their blocks
(`cycles_of`), so a deleted flight's cycles are read by none.  Any bad flight refuses
the whole request (422 naming the flight and the field) before anything is written.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import pandas as pd
from sqlalchemy import Select, delete, null, select
from sqlalchemy.orm import Session

from app.config import Settings
from app.services.records import plausibility
from app.storage import bulk, chunks
from app.tables import Flight, FlightBlock, SpectrumBlock
from model.cycle_counting import CycleError, FlightCycles, from_cycles, from_history
from model.records import RecordError
from model.spectrum_files import CycleTable, cycle_table

LOAD_FORMS = ("stress_range_mpa", "cycles", "stress_history_mpa")


class Recorded(NamedTuple):
    """What a stored flight recorded besides one range: its cycles and the history they came
    from."""

    recorded: str  # "cycles" or "stress_history"
    cycles: FlightCycles
    stress_history_mpa: np.ndarray | None = None


@dataclass(frozen=True)
class RecordedLoads:
    """What the flights of one ingest recorded besides one range, column-wise: flight f is row f
    of the flights frame handed to the ingest (whose validated rows are indexed by their 1-based
    source row, model.record_validation), with its tail and flight_id; recorded[f] is "cycles",
    "stress_history" or None (one range, no cycles in `cycles`); histories: the histories sent,
    by flight.  One object, not one per flight: a cycle file holds hundreds of thousands."""

    tail: np.ndarray  # (flights,) object
    flight_id: np.ndarray  # (flights,) object
    recorded: np.ndarray  # (flights,) object
    cycles: CycleTable
    histories: dict[int, np.ndarray]

    def cycled(self, rows: np.ndarray) -> np.ndarray:
        """bool (rows,): whether each flight at a 1-based row sent cycles (or a history), its
        range then their damage-equivalent one."""
        return pd.notna(self.recorded[np.asarray(rows, dtype=np.int64) - 1])


def with_ranges(
    tail: str, flights: Sequence[dict[str, Any]], settings: Settings, source: str = "body"
) -> tuple[list[dict[str, Any]], RecordedLoads | None]:
    """Each flight of `tail` with its one stress_range_mpa (as sent, or its cycles'
    damage-equivalent range), and what the flights sent as cycles or histories recorded (None
    where every flight sent one range).  Raises RecordError (row: the flight's 1-based
    position) naming the flight and the field."""
    law, bounds = settings.law(), plausibility.Bounds.of(settings)
    out: list[dict[str, Any]] = []
    kinds: list[str | None] = []
    counted: list[FlightCycles] = []
    histories: dict[int, np.ndarray] = {}
    for row, flight in enumerate(flights, start=1):
        name = flight.get("flight_id")
        given = [form for form in LOAD_FORMS if flight.get(form) is not None]
        if len(given) != 1:
            raise RecordError(
                source,
                row,
                given[-1] if given else "stress_range_mpa",
                f"flight {name!r}: give exactly one of {', '.join(LOAD_FORMS)}, "
                f"got {', '.join(given) or 'none'}",
            )
        if given[0] == "stress_range_mpa":
            out.append(flight)
            kinds.append(None)
            counted.append(_NO_CYCLES)
            continue
        try:
            if given[0] == "cycles":
                cycles = from_cycles(flight["cycles"])
                kinds.append("cycles")
            else:
                cycles = from_history(flight["stress_history_mpa"])
                histories[row - 1] = np.asarray(flight["stress_history_mpa"], dtype=np.float64)
                kinds.append("stress_history")
        except CycleError as exc:
            raise RecordError(source, row, exc.field, f"flight {name!r}: {exc}") from exc
        _check_cycles(cycles, flight, bounds, source, row)
        equivalent = cycles.equivalent_range(settings.growth_law, law.constants)
        out.append({**flight, "stress_range_mpa": equivalent})
        counted.append(cycles)
    if not any(kinds):
        return out, None
    sizes = np.array([len(c) for c in counted], dtype=np.int64)
    table = np.concatenate([np.stack(c.columns, axis=1) for c in counted]).reshape(-1, 3)
    return out, RecordedLoads(
        np.array([tail] * len(out), dtype=object),
        np.array([str(f.get("flight_id")) for f in out], dtype=object),
        np.array(kinds, dtype=object),
        CycleTable(np.ascontiguousarray(table), np.concatenate(([0], np.cumsum(sizes)))),
        histories,
    )


_NO_CYCLES = FlightCycles(np.zeros(0), np.zeros(0), np.zeros(0))


def _check_cycles(
    cycles: FlightCycles,
    flight: dict[str, Any],
    bounds: plausibility.Bounds,
    source: str,
    row: int,
) -> None:
    """Raise RecordError naming the flight's first cycle above the plausible range: the field
    of the cycle sent (its range, or the cycle itself where it came as its max and min), or the
    history whose rainflow counted it."""
    found = plausibility.first_implausible_cycle(cycles.stress_range_mpa, bounds)
    if found is None:
        return
    at, reason = found
    if flight.get("cycles") is None:
        field = "stress_history_mpa"
        reason = f"{reason} (counted by rainflow)"
    elif flight["cycles"][at].get("stress_range_mpa") is not None:
        field = f"cycles[{at}].stress_range_mpa"
    else:
        field = f"cycles[{at}]"
        reason = f"{reason} (max_stress_mpa - min_stress_mpa)"
    raise RecordError(source, row, field, f"flight {flight.get('flight_id')!r}: {reason}")


def from_cycle_file(
    frame: pd.DataFrame, source: str, settings: Settings
) -> tuple[pd.DataFrame, RecordedLoads]:
    """A cycle file (model.spectrum_files) as flights with their damage-equivalent ranges under
    the configured law, and their cycles.  Raises RecordError naming the file's first row whose
    cycle lies above the plausible range (app.services.records.plausibility)."""
    if "stress_range_mpa" in frame.columns:  # a missing column is cycle_table's to name
        ranges = pd.to_numeric(frame["stress_range_mpa"], errors="coerce")
        bounds = plausibility.Bounds.of(settings)
        found = plausibility.first_implausible_cycle(ranges.to_numpy(np.float64), bounds)
        if found is not None:
            raise RecordError(source, found[0] + 1, "stress_range_mpa", found[1])
    flights, cycles = cycle_table(frame, source, settings.growth_law, settings.law().constants)
    recorded = np.full(len(flights), "cycles", dtype=object)
    tails = flights["tail"].to_numpy(dtype=object)
    return flights, RecordedLoads(
        tails, flights["flight_id"].to_numpy(dtype=object), recorded, cycles, {}
    )


def is_cycle_file(frame: pd.DataFrame) -> bool:
    """A flights upload that holds one row per cycle (it has a load_ratio column)."""
    return "load_ratio" in frame.columns


def store(session: Session, new: pd.DataFrame, recorded: RecordedLoads) -> None:
    """The spectrum_blocks and flight_blocks rows of the newly stored flights (`new`: the
    ingest's validated rows that were inserted, indexed by source row, with tail, flight_id,
    aircraft_id and the id each was given, app.services.records.ingest with_ids) that recorded
    cycles: one block per tail, its flights in the upload's order.  In the caller's
    transaction, through the dialect's bulk path (executemany on SQLite, one binary COPY on
    PostgreSQL); the blocks' ids are reserved first (app.storage next_ids), so nothing is
    read back."""
    rows = new.index.to_numpy(dtype=np.int64) - 1
    chosen = recorded.recorded[rows] != None  # noqa: E711 - elementwise on an object array
    if not chosen.any():
        return
    rows = rows[chosen]
    inserted = new[chosen]
    # internal invariant: the validated rows are the flights `recorded` describes, in order
    assert (recorded.flight_id[rows] == inserted["flight_id"].to_numpy(dtype=object)).all()
    assert (recorded.tail[rows] == inserted["tail"].to_numpy(dtype=object)).all()
    aircraft = inserted["aircraft_id"].to_numpy(dtype=np.int64)
    order = np.argsort(aircraft, kind="stable")
    tails, first = np.unique(aircraft[order], return_index=True)
    bounds = np.append(first, len(order))
    storage = bulk(session.connection())
    ids = storage.next_ids(SpectrumBlock.__table__, len(tails))  # type: ignore[arg-type]
    in_block = np.empty(len(rows), dtype=np.int64)
    index = np.empty(len(rows), dtype=np.int64)
    columns: dict[str, list[Any]] = {name: [] for name in _BLOCK_COLUMNS}
    for k, tail in enumerate(tails.tolist()):
        members = order[bounds[k] : bounds[k + 1]]
        in_block[members] = ids[k]
        index[members] = np.arange(len(members))
        cycles, cycle_starts = recorded.cycles.block(rows[members])
        histories = (
            [recorded.histories.get(row) for row in rows[members].tolist()]
            if recorded.histories  # none in a cycle file
            else []
        )
        columns["id"].append(int(ids[k]))
        columns["aircraft_id"].append(tail)
        columns["cycle_starts"].append(cycle_starts.astype("<i8").tobytes())
        columns["cycles"].append(cycles)
        if any(h is not None for h in histories):
            sizes = [0 if h is None else len(h) for h in histories]
            starts = np.concatenate(([0], np.cumsum(sizes))).astype("<i8")
            columns["history_starts"].append(starts.tobytes())
            columns["stress_history_mpa"].append(
                b"".join(h.astype("<f8").tobytes() for h in histories if h is not None)
            )
        else:
            columns["history_starts"].append(None)
            columns["stress_history_mpa"].append(None)
    storage.insert(SpectrumBlock.__table__, columns)  # type: ignore[arg-type]
    storage.insert(
        FlightBlock.__table__,  # type: ignore[arg-type]
        {
            "flight_pk": inserted["id"].tolist(),
            "spectrum_block_id": in_block.tolist(),
            "spectrum_index": index.tolist(),
        },
    )


_BLOCK_COLUMNS = (
    "id",
    "aircraft_id",
    "cycle_starts",
    "history_starts",
    "cycles",
    "stress_history_mpa",
)


@dataclass(frozen=True)
class _Block:
    """A spectrum_blocks row as arrays (views of its bytes)."""

    cycle_starts: np.ndarray  # (flights + 1,) int64
    cycles: np.ndarray  # (cycles, 3) float64
    history_starts: np.ndarray | None  # (flights + 1,) int64
    histories: np.ndarray | None  # (points,) float64, MPa

    def history(self, at: int) -> np.ndarray | None:
        if self.history_starts is None or self.histories is None:
            return None
        first, last = self.history_starts[at], self.history_starts[at + 1]
        return self.histories[first:last].copy() if last > first else None


def _blocks(session: Session, ids: Iterable[int], *, histories: bool = False) -> dict[int, _Block]:
    """The blocks by id; their recorded stress histories only where asked (a sampled series
    can outweigh its cycles, and the cycles' readers never look at it)."""
    history_columns = (
        (SpectrumBlock.history_starts, SpectrumBlock.stress_history_mpa)
        if histories
        else (null().label("history_starts"), null().label("stress_history_mpa"))
    )
    found: dict[int, _Block] = {}
    for part in chunks(sorted(set(ids))):
        for row in session.execute(
            select(
                SpectrumBlock.id, SpectrumBlock.cycle_starts, SpectrumBlock.cycles, *history_columns
            ).where(SpectrumBlock.id.in_(part))
        ):
            found[row.id] = _Block(
                np.frombuffer(row.cycle_starts, dtype="<i8"),
                np.frombuffer(row.cycles, dtype="<f8").reshape(-1, 3),
                None if row.history_starts is None else np.frombuffer(row.history_starts, "<i8"),
                None
                if row.stress_history_mpa is None
                else np.frombuffer(row.stress_history_mpa, "<f8"),
            )
    return found


def cycles_of(session: Session, block_ids: np.ndarray, index: np.ndarray) -> CycleTable:
    """The stored cycles of flights that recorded them, back to back in the given order
    (block_ids, index: (flights,) each flight's spectrum_block_id and spectrum_index as read
    from its flight_blocks row, so only what stored flights refer to is read).  Raises LookupError where a
    flight refers to a missing block."""
    block_ids = np.asarray(block_ids, dtype=np.int64)
    index = np.asarray(index, dtype=np.int64)
    blocks = _blocks(session, np.unique(block_ids).tolist())
    order = np.argsort(block_ids, kind="stable")
    held, group_first = np.unique(block_ids[order], return_index=True)
    bounds = np.append(group_first, len(order))
    first = np.zeros(len(block_ids), dtype=np.int64)
    sizes = np.zeros(len(block_ids), dtype=np.int64)
    for k, block_id in enumerate(held.tolist()):
        if block_id not in blocks:
            raise LookupError(f"spectrum block {block_id} referred to by a flight is missing")
        members = order[bounds[k] : bounds[k + 1]]
        starts = blocks[block_id].cycle_starts
        first[members] = starts[index[members]]
        sizes[members] = starts[index[members] + 1] - first[members]
    out_starts = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
    table = np.empty((int(out_starts[-1]), 3), dtype=np.float64)
    for k, block_id in enumerate(held.tolist()):
        members = order[bounds[k] : bounds[k + 1]]
        source, at, n = first[members], out_starts[members], sizes[members]
        cycles = blocks[block_id].cycles
        if (source[1:] == (source + n)[:-1]).all() and (at[1:] == (at + n)[:-1]).all():
            table[at[0] : at[-1] + n[-1]] = cycles[source[0] : source[-1] + n[-1]]
        else:
            total = int(n.sum())
            table[_ranges(at, n, total)] = cycles[_ranges(source, n, total)]
    return CycleTable(table, out_starts)


def _ranges(first: np.ndarray, sizes: np.ndarray, total: int) -> np.ndarray:
    """first[k], first[k] + 1, ..., first[k] + sizes[k] - 1 for every k, back to back."""
    return np.repeat(first - (np.cumsum(sizes) - sizes), sizes) + np.arange(total)


def blobs_of(
    session: Session, block_ids: Sequence[int | None], index: Sequence[int | None]
) -> list[bytes | None]:
    """Each flight's stored cycles as FlightCycles.packed bytes, None where it recorded one
    range (block_ids, index: as cycles_of, None for such a flight)."""
    recorded = [i for i, block in enumerate(block_ids) if block is not None]
    out: list[bytes | None] = [None] * len(block_ids)
    if not recorded:
        return out
    table = cycles_of(
        session,
        np.array([block_ids[i] for i in recorded], dtype=np.int64),
        np.array([index[i] for i in recorded], dtype=np.int64),
    )
    data = table.table.astype("<f8", copy=False).tobytes()
    for k, i in enumerate(recorded):
        out[i] = data[24 * table.starts[k] : 24 * table.starts[k + 1]]
    return out


def _refs() -> Select[int, int]:
    """Where stored flights' cycles are (flights recorded as one range have none)."""
    return select(FlightBlock.spectrum_block_id, FlightBlock.spectrum_index).join(
        Flight, Flight.id == FlightBlock.flight_pk
    )


def block_of(session: Session, flight_pk: int) -> int | None:
    """The block holding a stored flight's cycles, None for a flight recorded as one range."""
    return session.scalar(
        select(FlightBlock.spectrum_block_id).where(FlightBlock.flight_pk == flight_pk)
    )


def drop_unreferenced(session: Session, aircraft_id: int, block_id: int) -> None:
    """Delete the tail's block `block_id` where none of its flights is left (after a flight's
    deletion; the cycles of a deleted flight in a block still in use are simply never read)."""
    referred = (
        select(FlightBlock.flight_pk)
        .join(Flight, Flight.id == FlightBlock.flight_pk)
        .where(Flight.aircraft_id == aircraft_id, FlightBlock.spectrum_block_id == block_id)
        .exists()
    )
    session.execute(delete(SpectrumBlock).where(SpectrumBlock.id == block_id, ~referred))


def stored(session: Session, aircraft_id: int, flight_id: str) -> Recorded | None:
    """What a stored flight recorded besides its range, None for a one-range flight."""
    ref = session.execute(
        _refs().where(Flight.aircraft_id == aircraft_id, Flight.flight_id == flight_id)
    ).one_or_none()
    if ref is None:
        return None
    block_id, at = ref.spectrum_block_id, ref.spectrum_index
    block = _blocks(session, [block_id], histories=True).get(block_id)
    if block is None:
        raise LookupError(f"spectrum block {block_id} referred to by a flight is missing")
    rows = block.cycles[block.cycle_starts[at] : block.cycle_starts[at + 1]]
    cycles = FlightCycles(rows[:, 0].copy(), rows[:, 1].copy(), rows[:, 2].copy())
    history = block.history(at)
    return Recorded("cycles" if history is None else "stress_history", cycles, history)


# the load ratio's bins on the tail page: compressive-going, low, mid and high-mean cycles
R_BINS = ((-np.inf, 0.0, "R < 0"), (0.0, 0.3, "0 ≤ R < 0.3"), (0.3, 0.6, "0.3 ≤ R < 0.6"))
R_TOP = (0.6, "R ≥ 0.6")


@dataclass(frozen=True)
class SpectraSummary:
    """A tail's flights recorded as cycles: how many, their cycles per flight (mean, counting
    half cycles as half) and each load-ratio bin's share of the cycles."""

    flights: int
    cycles_per_flight: float
    load_ratio_mix: tuple[tuple[str, float], ...]


def summary(session: Session, aircraft_id: int) -> SpectraSummary | None:
    """The tail's SpectraSummary, None where no flight of it was recorded as cycles."""
    refs = session.execute(_refs().where(Flight.aircraft_id == aircraft_id)).all()
    if not refs:
        return None
    block_ids, index = np.array(refs, dtype=np.int64).T
    table = cycles_of(session, block_ids, index).table
    ratio, count = table[:, 1], table[:, 2]
    total = float(count.sum())
    mix = [
        (label, float(count[(ratio >= low) & (ratio < high)].sum()) / total)
        for low, high, label in R_BINS
    ]
    mix.append((R_TOP[1], float(count[ratio >= R_TOP[0]].sum()) / total))
    return SpectraSummary(len(refs), total / len(refs), tuple(mix))
