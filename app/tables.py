"""ORM tables.  Never returned from routes: app.schemas (and schemas_forecasts, schemas_ops) hold
the API's shapes."""

from __future__ import annotations

import secrets
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    CheckConstraint,
    DateTime,
    Dialect,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    String,
    Text,
    TypeDecorator,
    UniqueConstraint,
    false,
    text,
    true,
)
from sqlalchemy.orm import Mapped, mapped_column

from app.db import Base
from app.default_location import DEFAULT_LOCATION, DEFAULT_LOCATION_ID

# SQLite keeps 64-bit integers in INTEGER; only an INTEGER primary key is the auto-assigned rowid.
BigIntId = BigInteger().with_variant(Integer(), "sqlite")


# JSON whose Python None is SQL NULL: plain JSON stores None as the JSON text 'null', which
# `IS NULL` never finds (a row stored with bands=None would never be sampled by
# app.services.forecasts.cache_advance.fill_pending).
NULLABLE_JSON = JSON(none_as_null=True)


def new_stamp() -> int:
    """A random 63-bit value (a signed BIGINT): two rows' stamps agree by chance once in 2**63."""
    return secrets.randbits(63)


class UTCDateTime(TypeDecorator[datetime]):
    """Timestamps stored in UTC and always read back timezone-aware (SQLite stores them naive)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("naive datetime: timestamps must carry a timezone")
        value = value.astimezone(UTC)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


def utc_now() -> datetime:
    return datetime.now(UTC)


ROLES = ("read", "write", "admin")  # each role may do what the ones before it may


class ApiKey(Base):
    """An API key: the public key_id names it, only a salted SHA-256 of its secret is stored
    (app.services.keys).  Revoked keys stay, so the audit events they signed keep their name."""

    __tablename__ = "api_keys"
    __table_args__ = (
        CheckConstraint("role IN ('read', 'write', 'admin')", name="role_known"),
        # One live key per name: `fleetpinn keys create --replace` revokes the old one first.
        Index(
            "uq_api_keys_live_name",
            "name",
            unique=True,
            sqlite_where=text("revoked_at IS NULL"),
            postgresql_where=text("revoked_at IS NULL"),
        ),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    key_id: Mapped[str] = mapped_column(String(16), unique=True)
    name: Mapped[str] = mapped_column(String(64))
    role: Mapped[str] = mapped_column(String(8))
    salt: Mapped[str] = mapped_column(String(32))
    key_hash: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utc_now)
    revoked_at: Mapped[datetime | None] = mapped_column(UTCDateTime)


class AuditEvent(Base):
    """One write: who (the key, or a local command), when, what, and what it replaced.

    Flights, inspections and jobs point at the event that stored (or last corrected) them;
    detail holds the counts of an ingest, the values before and after a correction, the row a
    deletion removed, a retrain's parameters or an activation's previous version.
    """

    __tablename__ = "audit_events"
    __table_args__ = (Index("ix_audit_events_subject", "subject"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    at: Mapped[datetime] = mapped_column(UTCDateTime, default=utc_now)
    api_key_id: Mapped[int | None] = mapped_column(ForeignKey("api_keys.id"))
    # The key's name when it wrote (or "cli:<command>" for a local command without a key).
    actor: Mapped[str] = mapped_column(String(80))
    role: Mapped[str] = mapped_column(String(8))
    action: Mapped[str] = mapped_column(String(32))
    subject: Mapped[str] = mapped_column(String(300))
    request_id: Mapped[str | None] = mapped_column(String(128))
    detail: Mapped[dict[str, Any]] = mapped_column(JSON)


# the default location (re-exported: the tables' users read it here)
__all__ = ["DEFAULT_LOCATION", "DEFAULT_LOCATION_ID"]


class Location(Base):
    """A control point of the fleet's catalogue (app.services.records.locations): how a recorded load
    becomes its local stress, its crack physics and how it is inspected.  A None value means
    the model's own (the service's settings), so the default location, all None, answers as
    the service did before locations."""

    __tablename__ = "locations"
    __table_args__ = (
        CheckConstraint("stress_factor > 0", name="stress_factor_positive"),
        CheckConstraint("critical_crack_m > initial_crack_m", name="critical_above_initial"),
        CheckConstraint("pod_a90_m > pod_a50_m", name="pod_a90_above_a50"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True)
    description: Mapped[str] = mapped_column(Text, default="", server_default="")
    # local stress range per unit of the recorded one; per mission where the table names it
    stress_factor: Mapped[float] = mapped_column(Float, default=1.0, server_default="1")
    stress_factor_by_mission: Mapped[dict[str, float] | None] = mapped_column(NULLABLE_JSON)
    # a constant, or {"crack_length_m": [...], "factor": [...]} interpolated over the crack
    geometry_factor: Mapped[float | None] = mapped_column(Float)
    geometry_table: Mapped[dict[str, list[float]] | None] = mapped_column(NULLABLE_JSON)
    initial_crack_m: Mapped[float | None] = mapped_column(Float)
    critical_crack_m: Mapped[float | None] = mapped_column(Float)
    material: Mapped[str | None] = mapped_column(String(128))
    # {"law": "paris", "paris_c": .., "paris_m": ..} or {"law": "paris", "learn": true}
    growth_law: Mapped[dict[str, Any] | None] = mapped_column(NULLABLE_JSON)
    inspection_method: Mapped[str | None] = mapped_column(String(128))
    sizing_relative_sd: Mapped[float | None] = mapped_column(Float)
    pod_a50_m: Mapped[float | None] = mapped_column(Float)
    pod_a90_m: Mapped[float | None] = mapped_column(Float)
    # {"type": ..., dimensions} of model.crack_cases, and what its critical crack needs
    crack_case: Mapped[dict[str, Any] | None] = mapped_column(NULLABLE_JSON)
    limit_stress_mpa: Mapped[float | None] = mapped_column(Float)
    fracture_toughness_mpa_sqrt_m: Mapped[float | None] = mapped_column(Float)
    yield_strength_mpa: Mapped[float | None] = mapped_column(Float)
    # Walker's gamma for cycles at R < 0 (None: the R >= 0 gamma; 0: compression ignored)
    gamma_below_zero: Mapped[float | None] = mapped_column(Float)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utc_now)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utc_now, onupdate=utc_now)


class AircraftLocation(Base):
    """An aircraft's listed subset of the catalogue (app.services.records.locations.carried): an
    aircraft without rows here carries every location."""

    __tablename__ = "aircraft_locations"

    aircraft_id: Mapped[int] = mapped_column(
        ForeignKey("aircraft.id", ondelete="CASCADE"), primary_key=True
    )
    location_id: Mapped[int] = mapped_column(
        ForeignKey("locations.id", ondelete="CASCADE"), primary_key=True
    )


class Aircraft(Base):
    __tablename__ = "aircraft"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    tail: Mapped[str] = mapped_column(String(64), unique=True)
    # None: the Paris-law default initial crack of the model in use.
    initial_crack_m: Mapped[float | None] = mapped_column(Float)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utc_now)


class Flight(Base):
    __tablename__ = "flights"
    # The unique index doubles as the per-aircraft lookup index.  An index on (aircraft_id,
    # flown_at) was measured: GET /aircraft pages ~2.5x faster, but the fleet bulk upload went
    # from 1.9x to 2.5x the bare sqlite3 load (goal: <= 3x), so it is left out.
    __table_args__ = (
        UniqueConstraint("aircraft_id", "flight_id"),
        CheckConstraint("stress_range_mpa > 0", name="stress_range_positive"),
    )

    id: Mapped[int] = mapped_column(BigIntId, primary_key=True)
    # aircraft_id and audit_id refer to aircraft.id and audit_events.id without a declared
    # foreign key: PostgreSQL checks one per inserted row, which tripled the time of a bulk
    # upload.  Triggers keep the same guarantees with one check per statement (deleting an
    # aircraft deletes its flights; migration 9c4d2e7f1a30 says how).
    aircraft_id: Mapped[int] = mapped_column(Integer)
    flight_id: Mapped[str] = mapped_column(String(128))
    flown_at: Mapped[datetime] = mapped_column(UTCDateTime)
    stress_range_mpa: Mapped[float] = mapped_column(Float)
    mission: Mapped[str | None] = mapped_column(String(64))
    # The write that stored or last corrected the flight (None: stored before the audit log).
    audit_id: Mapped[int | None] = mapped_column(Integer)


class SpectrumBlock(Base):
    """What one upload's flights of one tail recorded besides their one range (migration
    20261130_5b8e1f3c7a92): their cycles (range, load ratio, count; counted by rainflow from a
    stress history at ingest) and the histories where they were sent, back to back, so that a
    later growth law can be refitted to them (model.cycle_counting).  A flight's FlightBlock
    row names its block and its place in it; only what a stored flight's row names is ever read
    (app.services.records.spectra), so deleting a flight (its row cascades) removes its cycles from every
    reader, and the block goes when none of its flights is left (or with its aircraft).  One row per tail and upload, not per flight: 2.19 M rows of a 192-byte blob
    were SQLite's B-tree work of 7.5 s per upload (benchmarks/RESULTS.md, issue 21).
    flights.stress_range_mpa holds the cycles' damage-equivalent range under the law
    configured when they were stored."""

    __tablename__ = "spectrum_blocks"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    aircraft_id: Mapped[int] = mapped_column(ForeignKey("aircraft.id", ondelete="CASCADE"))
    # the small columns first: SQLite reads a row's columns in order, through the blobs' pages
    # (flights + 1,) little-endian int64: flight k's cycles are rows starts[k]:starts[k + 1]
    cycle_starts: Mapped[bytes] = mapped_column(LargeBinary)
    # (flights + 1,) little-endian int64 into stress_history_mpa, None where no flight of the
    # block sent a history; an empty one: the flight sent cycles
    history_starts: Mapped[bytes | None] = mapped_column(LargeBinary)
    # (cycles, 3) little-endian float64: stress_range_mpa, load_ratio, count
    cycles: Mapped[bytes] = mapped_column(LargeBinary)
    # the histories as sent, back to back (little-endian float64, MPa)
    stress_history_mpa: Mapped[bytes | None] = mapped_column(LargeBinary)


class FlightBlock(Base):
    """Where a flight recorded as cycles has them (app.tables.SpectrumBlock): its block and its
    place in it.  A narrow row per such flight, deleted with its flight (cascade), so the
    flights table and the single-range upload are as they were: two nullable columns on
    flights instead made that upload's insert ~1.6x slower in the service (measured, not
    explained: bare SQLite showed no difference).  The block is no declared foreign key (as
    flights.aircraft_id is not: PostgreSQL checks one per row); it is written in the same
    transaction and deleted only when no row names it (app.services.records.spectra)."""

    __tablename__ = "flight_blocks"

    flight_pk: Mapped[int] = mapped_column(
        BigIntId, ForeignKey("flights.id", ondelete="CASCADE"), primary_key=True
    )
    spectrum_block_id: Mapped[int] = mapped_column(Integer)
    spectrum_index: Mapped[int] = mapped_column(Integer)


class Inspection(Base):
    """A crack measurement, or a non-detection (detected false: the crack was probably below
    the detection threshold or PoD curve), optionally followed by a repair that restarts the
    crack at crack_after_repair_m.  model.record_validation.validate_inspections checks the
    combinations."""

    __tablename__ = "inspections"
    __table_args__ = (
        UniqueConstraint("aircraft_id", "inspection_id"),
        CheckConstraint("crack_length_m > 0", name="crack_length_positive"),
        CheckConstraint("crack_after_repair_m > 0", name="crack_after_repair_positive"),
        CheckConstraint("detected OR crack_length_m IS NULL", name="no_crack_when_not_detected"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    aircraft_id: Mapped[int] = mapped_column(ForeignKey("aircraft.id", ondelete="CASCADE"))
    inspection_id: Mapped[str] = mapped_column(String(128))
    # where on the aircraft (the catalogue's location); the default one unless named (a server
    # default, so bulk inserts that do not name it, as before locations, store the default)
    location_id: Mapped[int] = mapped_column(
        ForeignKey("locations.id"), server_default=str(DEFAULT_LOCATION_ID)
    )
    inspected_at: Mapped[datetime] = mapped_column(UTCDateTime)
    # None exactly where detected is false.
    crack_length_m: Mapped[float | None] = mapped_column(Float)
    detected: Mapped[bool] = mapped_column(Boolean, default=True, server_default=true())
    detection_threshold_m: Mapped[float | None] = mapped_column(Float)
    pod_a50_m: Mapped[float | None] = mapped_column(Float)
    pod_a90_m: Mapped[float | None] = mapped_column(Float)
    repaired: Mapped[bool] = mapped_column(Boolean, default=False, server_default=false())
    crack_after_repair_m: Mapped[float | None] = mapped_column(Float)
    audit_id: Mapped[int | None] = mapped_column(ForeignKey("audit_events.id"))
    # How the inspection compared with its tail's forecast when it was stored or corrected
    # (app.services.forecasts.assessment): the forecast crack then, the z-score of the finding, and
    # whether it disagreed strongly.  None: there was no forecast (no active model, no flights).
    forecast_crack_m: Mapped[float | None] = mapped_column(Float)
    forecast_z: Mapped[float | None] = mapped_column(Float)
    flagged: Mapped[bool] = mapped_column(Boolean, default=False, server_default=false())


class ModelVersion(Base):
    __tablename__ = "model_versions"
    __table_args__ = (
        CheckConstraint("status IN ('candidate', 'active', 'retired')", name="status_known"),
        Index("ix_model_versions_status", "status"),
        # At most one active version per location: activation retires the previous one in the
        # same transaction.
        Index(
            "uq_model_versions_one_active",
            "location_id",
            "status",
            unique=True,
            sqlite_where=text("status = 'active'"),
            postgresql_where=text("status = 'active'"),
        ),
    )

    version: Mapped[int] = mapped_column(Integer, primary_key=True)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utc_now)
    activated_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    status: Mapped[str] = mapped_column(String(16), default="candidate")
    spec: Mapped[dict[str, Any]] = mapped_column(JSON)
    training: Mapped[dict[str, Any]] = mapped_column(JSON)
    metrics: Mapped[dict[str, Any]] = mapped_column(JSON)
    weights: Mapped[bytes] = mapped_column(LargeBinary)
    job_id: Mapped[str | None] = mapped_column(String(36))
    # The location (app.services.records.locations) whose inspections trained it and whose forecasts
    # it serves.  No declared foreign key: SQLite adds a column with one only by copying the
    # table, whose drop would cascade to every cached forecast; catalogue entries are never
    # deleted.
    location_id: Mapped[int] = mapped_column(Integer, server_default=str(DEFAULT_LOCATION_ID))


class Job(Base):
    __tablename__ = "jobs"
    __table_args__ = (
        CheckConstraint(
            "status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')",
            name="status_known",
        ),
        Index("ix_jobs_status_created_at", "status", "created_at"),
    )

    id: Mapped[str] = mapped_column(String(36), primary_key=True)
    kind: Mapped[str] = mapped_column(String(32))
    status: Mapped[str] = mapped_column(String(16), default="queued")
    progress: Mapped[float] = mapped_column(Float, default=0.0)
    # What a running job is doing now, in words ("fitting the model"); set with its progress.
    stage: Mapped[str | None] = mapped_column(String(64))
    params: Mapped[dict[str, Any]] = mapped_column(JSON)
    result: Mapped[dict[str, Any] | None] = mapped_column(NULLABLE_JSON)
    error: Mapped[str | None] = mapped_column(Text)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, default=False)
    worker: Mapped[str | None] = mapped_column(String(128))
    # Runs so far; a running job whose heartbeat stops is claimed again, up to MAX_ATTEMPTS.
    attempts: Mapped[int] = mapped_column(Integer, default=0, server_default="0")
    heartbeat_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utc_now)
    started_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    audit_id: Mapped[int | None] = mapped_column(ForeignKey("audit_events.id"))


class Forecast(Base):
    """Where each tail stands under one model version: the cache single forecasts start from.

    Keyed by subject (aircraft, location) and version.  Rows of a tail are deleted
    (app.services.forecasts.forecast_cache.invalidate) when its flights, its
    repairs or its initial crack change.
    """

    __tablename__ = "forecasts"
    # The stamps alone, read without the row: SQLite stores the stamp after the bands (tens of
    # KB in overflow pages), which a read of the row's stamp walked through (a ranking's stamps
    # took 2.8 ms that way).
    __table_args__ = (
        Index("ix_forecasts_version_stamp", "model_version", "aircraft_id", "location_id", "stamp"),
    )

    # The subject (app.services.forecasts.cache_rows.Subject): an aircraft's location.
    aircraft_id: Mapped[int] = mapped_column(
        ForeignKey("aircraft.id", ondelete="CASCADE"), primary_key=True
    )
    location_id: Mapped[int] = mapped_column(
        ForeignKey("locations.id", ondelete="CASCADE"),
        primary_key=True,
        server_default=str(DEFAULT_LOCATION_ID),
    )
    model_version: Mapped[int] = mapped_column(
        ForeignKey("model_versions.version", ondelete="CASCADE"), primary_key=True
    )
    computed_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utc_now)
    flights_flown: Mapped[int] = mapped_column(Integer)
    first_flown_at: Mapped[datetime] = mapped_column(UTCDateTime)
    origin: Mapped[datetime] = mapped_column(UTCDateTime)
    crack_length_m: Mapped[float] = mapped_column(Float)
    flights_per_day: Mapped[float] = mapped_column(Float)
    flights_to_critical: Mapped[int | None] = mapped_column(Integer)
    critical_date: Mapped[datetime | None] = mapped_column(UTCDateTime)
    # Uncertainty (app.services.forecasts.forecast_cache): the crack after the last flight under each
    # posterior sample, float64 bytes (samples,); the recent stress ranges future usage is
    # resampled from, float64 bytes; per horizon_days (as text) the sampled summary, and the
    # daily bands.
    crack_samples_m: Mapped[bytes | None] = mapped_column(LargeBinary)
    # ln growth factor of each sample (model.tracking), and its summary with the evidence
    growth_samples: Mapped[bytes | None] = mapped_column(LargeBinary)
    growth: Mapped[dict[str, Any] | None] = mapped_column(NULLABLE_JSON)
    recent_stress_mpa: Mapped[bytes | None] = mapped_column(LargeBinary)
    risk: Mapped[dict[str, Any] | None] = mapped_column(NULLABLE_JSON)
    bands: Mapped[dict[str, Any] | None] = mapped_column(NULLABLE_JSON)
    # A new random value on every insert and update of the row, by any writer (the ORM and
    # update() statements alike): whoever keeps something derived from a row (the encoded
    # answers of app.services.forecasts.forecast_answers and app.services.ranking.ranking_answers)
    # serves it only while the row's stamp is the one it was derived from.  NULL (rows stored before the column): never kept.
    stamp: Mapped[int | None] = mapped_column(BigInteger, default=new_stamp, onupdate=new_stamp)
