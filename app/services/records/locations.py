"""The fleet's catalogue of control points (table locations), and a recorded load at one.

Loads are stored once per flight per aircraft (the far-field stress range of the flight);
each location sees them times its stress transfer factor, its mission's where its table names
the flight's mission (local_stress).  The default location (created by the migration that
brought locations) has factor 1 and the model's physics, so it sees the recorded loads as they
are and answers as the service did before locations.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from types import SimpleNamespace
from typing import Any

import numpy as np
import pandas as pd
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.config import Settings
from app.errors import NotFoundError
from app.services import audit
from app.services.forecasts import cache_rows
from app.services.records import location_cracks
from app.tables import DEFAULT_LOCATION, DEFAULT_LOCATION_ID, Location
from model.geometry import GeometryTable
from model.materials import law_for
from model.physics import ParisLaw
from model.posterior import SizingError
from model.records import RecordError

# a crack case and what its critical crack needs (app.services.records.location_cracks), and
# Walker's gamma below R = 0 (issue 41's additions)
CRACK_CASE_FIELDS = (
    "crack_case",
    "limit_stress_mpa",
    "fracture_toughness_mpa_sqrt_m",
    "yield_strength_mpa",
    "gamma_below_zero",
)
# the catalogue's values as PUT sends them and GET answers them
FIELDS = (
    "description",
    "stress_factor",
    "stress_factor_by_mission",
    "geometry_factor",
    "geometry_table",
    "initial_crack_m",
    "critical_crack_m",
    "material",
    "growth_law",
    "inspection_method",
    "sizing_relative_sd",
    "pod_a50_m",
    "pod_a90_m",
    *CRACK_CASE_FIELDS,
)


@dataclass(frozen=True)
class StoredLocation:
    """A catalogue entry as stored (app.schemas_locations.LocationOut reads it)."""

    id: int
    name: str
    description: str
    stress_factor: float
    stress_factor_by_mission: dict[str, float] | None
    geometry_factor: float | None
    geometry_table: dict[str, list[float]] | None
    initial_crack_m: float | None
    critical_crack_m: float | None
    material: str | None
    growth_law: dict[str, Any] | None
    inspection_method: str | None
    sizing_relative_sd: float | None
    pod_a50_m: float | None
    pod_a90_m: float | None
    created_at: datetime
    updated_at: datetime
    crack_case: dict[str, Any] | None = None
    limit_stress_mpa: float | None = None
    fracture_toughness_mpa_sqrt_m: float | None = None
    yield_strength_mpa: float | None = None
    gamma_below_zero: float | None = None

    @classmethod
    def of(cls, row: Location) -> StoredLocation:
        return cls(
            row.id,
            row.name,
            created_at=row.created_at,
            updated_at=row.updated_at,
            **{name: getattr(row, name) for name in FIELDS},
        )


def put_location(
    session: Session,
    name: str,
    values: dict[str, Any],
    *,
    actor: audit.Actor,
    settings: Settings,
) -> tuple[StoredLocation, bool]:
    """Create (True) or replace the catalogue entry `name` with `values` (every FIELDS key,
    validated by the schema), audited with what it replaced.  Commits.  Raises RecordError
    naming the field where the entry's cracks contradict the model's (an initial crack at or
    above the settings' critical one, or the reverse), or where its crack case cannot be used
    (app.services.records.location_cracks): nothing is stored."""
    if values.get("limit_stress_mpa") is None:  # else a_crit is the case's, checked there
        _check_cracks(values, settings)
    location_cracks.crack_case_answer(SimpleNamespace(**values), settings)
    try:
        return _put(session, name, values, actor)
    except IntegrityError:  # the same new name stored by a concurrent PUT: update it instead
        session.rollback()
        return _put(session, name, values, actor)


def _put(
    session: Session, name: str, values: dict[str, Any], actor: audit.Actor
) -> tuple[StoredLocation, bool]:
    row = session.scalars(select(Location).where(Location.name == name)).one_or_none()
    created = row is None
    before = None if row is None else {f: getattr(row, f) for f in FIELDS}
    if row is None:
        row = Location(name=name)
        session.add(row)
    for field in FIELDS:
        setattr(row, field, values.get(field))
    if row.stress_factor is None:
        row.stress_factor = 1.0
    if row.description is None:
        row.description = ""
    session.flush()
    detail = {"after": {f: values.get(f) for f in FIELDS}}
    if before is not None:
        detail["before"] = before
        # its cached forecasts were made under the entry replaced (its loads, its physics)
        cache_rows.drop_location(session, row.id)
    audit.record(session, actor, "location.create" if created else "location.update", name, detail)
    session.commit()
    return StoredLocation.of(row), created


def _check_cracks(values: dict[str, Any], settings: Settings) -> None:
    initial, critical = values.get("initial_crack_m"), values.get("critical_crack_m")
    base = settings.law()
    if initial is not None and critical is None and initial >= base.critical_crack_m:
        reason = (
            f"must be < the model's critical crack ({base.critical_crack_m:g} m), got {initial:g}"
        )
        raise RecordError("body", None, "initial_crack_m", reason)
    if critical is not None and initial is None and critical <= base.initial_crack_m:
        reason = (
            f"must be > the model's initial crack ({base.initial_crack_m:g} m), got {critical:g}"
        )
        raise RecordError("body", None, "critical_crack_m", reason)


def get_location(session: Session, name: str) -> StoredLocation:
    """The catalogue entry `name`; raises NotFoundError."""
    row = session.scalars(select(Location).where(Location.name == name)).one_or_none()
    if row is None:
        raise NotFoundError(f"unknown location {name!r}: PUT /locations/{name} first")
    return StoredLocation.of(row)


def location_id(session: Session, name: str | None) -> int:
    """The id of the location `name` (None: the default one, read nowhere); raises
    NotFoundError."""
    if name is None or name == DEFAULT_LOCATION:
        return DEFAULT_LOCATION_ID
    found = session.scalar(select(Location.id).where(Location.name == name))
    if found is None:
        raise NotFoundError(f"unknown location {name!r}: PUT /locations/{name} first")
    return int(found)


def location_by_id(session: Session, location_id: int) -> StoredLocation:
    """The catalogue entry with this id; raises NotFoundError."""
    row = session.get(Location, location_id)
    if row is None:
        raise NotFoundError(f"unknown location id {location_id}")
    return StoredLocation.of(row)


def locations_by_id(session: Session, location_ids: Sequence[int]) -> dict[int, StoredLocation]:
    """The catalogue entries with these ids, in one query (a ranking's page reads its rows'
    locations at once); raises NotFoundError naming an id not in the catalogue."""
    wanted = sorted(set(location_ids))
    if not wanted:
        return {}
    found = session.scalars(select(Location).where(Location.id.in_(wanted)))
    out = {row.id: StoredLocation.of(row) for row in found}
    for location_id in wanted:
        if location_id not in out:
            raise NotFoundError(f"unknown location id {location_id}")
    return out


def list_locations(session: Session) -> list[StoredLocation]:
    """The catalogue, by name."""
    return [StoredLocation.of(r) for r in session.scalars(select(Location).order_by(Location.name))]


def resolve(session: Session, names: pd.Series, source: str) -> np.ndarray:
    """The location id of each name (None or NaN: the default location), in order.  Raises
    RecordError naming the first row (1-based) with a location not in the catalogue."""
    ids = {name: ident for ident, name in session.execute(select(Location.id, Location.name))}
    out = np.empty(len(names), dtype=np.int64)
    for k, name in enumerate(names.tolist()):
        if name is None or (isinstance(name, float) and np.isnan(name)):
            out[k] = DEFAULT_LOCATION_ID
        elif name in ids:
            out[k] = ids[name]
        else:
            raise RecordError(
                source, k + 1, "location", f"unknown location {name!r}: PUT /locations/{name} first"
            )
    return out


# how a record file or body writes "not detected" (model.record_validation reads the same)
_NOT_DETECTED = frozenset({"false", "0", "no", "f", "n", "0.0"})


def with_method_pod(
    session: Session, records: pd.DataFrame, location_ids: np.ndarray
) -> pd.DataFrame:
    """records (inspections, positional location_ids) where each non-detection that gives
    neither a detection threshold nor a PoD curve takes its location's inspection method's
    (pod_a50_m, pod_a90_m): the catalogue's PoD, so a method's "nothing found" needs no curve of
    its own.  Rows that give one keep theirs; a location without a curve leaves the row as it
    is (validation then names the missing field)."""
    if "detected" not in records.columns or not len(records):
        return records
    text = records["detected"].astype(str).str.strip().str.lower()
    missed = text.isin(_NOT_DETECTED).to_numpy().copy()
    for column in ("detection_threshold_m", "pod_a50_m", "pod_a90_m"):
        if column in records.columns:
            given = records[column]
            missed &= (given.isna() | (given.astype(str).str.strip() == "")).to_numpy()
    if not missed.any():
        return records
    curves = {
        ident: (a50, a90)
        for ident, a50, a90 in session.execute(
            select(Location.id, Location.pod_a50_m, Location.pod_a90_m).where(
                Location.pod_a50_m.is_not(None)
            )
        )
    }
    out = records.copy()
    for q, column in enumerate(("pod_a50_m", "pod_a90_m")):
        values = out[column].astype(object).tolist() if column in out.columns else [None] * len(out)
        for k in np.flatnonzero(missed):
            curve = curves.get(int(location_ids[k]))
            if curve is not None:
                values[k] = curve[q]
        out[column] = pd.Series(values, index=out.index, dtype=object)
    return out


def names_of(session: Session, location_ids: Sequence[int]) -> dict[int, str]:
    """The name of each of these location ids."""
    wanted = sorted(set(location_ids))
    if wanted == [DEFAULT_LOCATION_ID]:
        return {DEFAULT_LOCATION_ID: DEFAULT_LOCATION}
    rows = session.execute(select(Location.id, Location.name).where(Location.id.in_(wanted)))
    return {ident: name for ident, name in rows}


def local_stress(flights: pd.DataFrame, location: StoredLocation) -> pd.DataFrame:
    """flights (columns stress_range_mpa and optionally mission) with the stress range this
    location sees: times its mission's factor where its table names the mission, else times
    stress_factor.  The recorded frame comes back untouched at factor 1 without a table."""
    if location.stress_factor == 1.0 and not location.stress_factor_by_mission:
        return flights
    missions = flights["mission"] if "mission" in flights.columns else None
    out = flights.copy()
    out["stress_range_mpa"] = scaled(
        out["stress_range_mpa"].to_numpy(np.float64), missions, location
    )
    return out


def scaled(
    stress_mpa: np.ndarray, missions: pd.Series | None, location: StoredLocation
) -> np.ndarray:
    """(flights,) recorded stress ranges as the location sees them (local_stress's rule)."""
    factor = np.full(len(stress_mpa), location.stress_factor, dtype=np.float64)
    table = location.stress_factor_by_mission or {}
    if table and missions is not None:
        by_mission = pd.Series(missions).reset_index(drop=True).map(table)
        named = by_mission.notna().to_numpy()
        factor[named] = by_mission[named].to_numpy(dtype=np.float64)
    return np.asarray(stress_mpa, dtype=np.float64) * factor


@dataclass(frozen=True)
class Physics:
    """What a location's retrain starts from: its Paris law (null values: the settings'),
    whether C and m are learned from its inspections, and its method's sizing error."""

    law: ParisLaw
    learn_paris: bool
    sizing: SizingError
    growth_law: str = "paris"  # model.growth_laws' name: the entry's, else the settings'


def physics(location: StoredLocation, settings: Settings) -> Physics:
    """The location's physics over its material's constants (the shipped table and the
    settings' materials_file, model.materials) and the settings' defaults.  A geometry table
    is the law's (model.geometry.GeometryTable: every march reads F at the current crack,
    linear between the points, held outside them), the calibration of C and m included
    (model.growth_integral); its value at the initial crack is the law's constant F.  A crack
    case gives the table (app.services.records.location_cracks) and, with a limit stress, a_crit.  Raises ValueError naming the constant where the mix is invalid (e.g. a
    catalogue a0 above the settings' a_crit)."""
    base = settings.law()
    if location.material is not None:
        base = law_for(location.material, base, settings.materials_file)
    initial = location.initial_crack_m or base.initial_crack_m
    geometry = location.geometry_factor or base.geometry_factor
    table = None
    if location.geometry_table is not None:
        table = GeometryTable.from_dict(location.geometry_table)
        geometry = table.value_at(initial)
    critical = location.critical_crack_m or base.critical_crack_m
    answer = location_cracks.crack_case_answer(location, settings)
    if answer is not None:  # the case's beta as a table, and its a_crit where it computes one
        table = answer.curve.table
        geometry = table.value_at(initial)
        critical = answer.critical_crack_m
    law_spec = location.growth_law or {}
    learn = bool(law_spec.get("learn", settings.learn_paris if not law_spec else False))
    law = ParisLaw(
        c=float(law_spec.get("paris_c") or base.c),
        m=float(law_spec.get("paris_m") or base.m),
        geometry_factor=geometry,
        initial_crack_m=initial,
        critical_crack_m=critical,
        gamma=float(law_spec.get("walker_gamma") or base.gamma),
        geometry_table=table,
        nasgro=base.nasgro,
        gamma_below_zero=location.gamma_below_zero,
    )
    sizing = settings.sizing()
    if location.sizing_relative_sd is not None:
        sizing = SizingError(location.sizing_relative_sd, sizing.absolute_sd_m)
    return Physics(law, learn, sizing, law_spec.get("law") or settings.growth_law)
