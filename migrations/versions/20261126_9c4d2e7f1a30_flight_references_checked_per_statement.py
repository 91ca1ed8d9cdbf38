"""Flights' references to aircraft and audit_events checked by triggers, not foreign keys.

Why: PostgreSQL checks a foreign key with one trigger call and one index probe per inserted
row.  A bulk upload of 2.19 M flights COPYs them into one table; its two foreign keys (aircraft,
then audit_events) made that COPY ~3x a bare COPY into a table with one unique index
(benchmarks/pg_copy.py, benchmarks/RESULTS.md).  An upload references ~300 aircraft and one
audit event, so the same guarantees are kept with one set-based check per statement.

What holds on both backends, for every writer (not only the service):
  * no flight refers to a missing aircraft or audit event: an INSERT or UPDATE (or COPY) that
    would store one fails with a foreign-key violation (PostgreSQL SQLSTATE 23503; SQLite
    SQLITE_CONSTRAINT), so its transaction stores nothing;
  * deleting an aircraft deletes its flights (was ON DELETE CASCADE); changing a referenced
    aircraft id, or deleting or renumbering a referenced audit event, fails (was NO ACTION).
PostgreSQL: an AFTER ... FOR EACH STATEMENT trigger reads the statement's new rows (a
transition table), takes their distinct aircraft and audit ids and locks those rows FOR KEY
SHARE, as the foreign key's own check does, so an aircraft deleted meanwhile either makes the
insert fail or waits for it and then deletes its flights too (READ COMMITTED, the service's
level).  SQLite has no statement triggers; its row triggers do what its foreign keys did, with
the same per-row index probe.  Inspections, forecasts and jobs keep their foreign keys: they are
written a few rows at a time.

Measured in one run (benchmarks/pg_copy.py, 2.19 M flights, against a bare COPY into a plain
table with one unique index): per-row foreign keys 4.9x, this statement check 1.33x, no check at
all 1.18x; COPY into a temporary table then INSERT ... SELECT ... ON CONFLICT 2.18x.
Trade-off: the rule lives in PL/pgSQL and SQLite triggers, not in a declared constraint (schema
tools and the ORM do not show it), and the race guarantee above assumes READ COMMITTED: a
REPEATABLE READ transaction deleting an aircraft would miss flights committed after its
snapshot, where a foreign key's cascade raises a serialization error.

Revision ID: 9c4d2e7f1a30
Revises: 7a3e91c2d4f0
Create Date: 2026-11-26
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "9c4d2e7f1a30"
down_revision: str | None = "7a3e91c2d4f0"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_FKS = (
    ("fk_flights_aircraft_id_aircraft", "aircraft", "aircraft_id", "CASCADE"),
    ("fk_flights_audit_id_audit_events", "audit_events", "audit_id", None),
)

_POSTGRESQL = (
    """
    CREATE FUNCTION flights_check_references() RETURNS trigger LANGUAGE plpgsql AS $$
    DECLARE
        aircraft_ids integer[];
        audit_ids integer[];
    BEGIN
        SELECT array_agg(DISTINCT used.aircraft_id),
               array_agg(DISTINCT used.audit_id) FILTER (WHERE used.audit_id IS NOT NULL)
          INTO aircraft_ids, audit_ids
          FROM (SELECT DISTINCT aircraft_id, audit_id FROM new_flights) AS used;
        IF cardinality(aircraft_ids) > (
            SELECT count(*) FROM (
                SELECT 1 FROM aircraft WHERE id = ANY(aircraft_ids) FOR KEY SHARE
            ) AS locked
        ) THEN
            RAISE EXCEPTION 'flights refer to an aircraft that does not exist'
                USING ERRCODE = 'foreign_key_violation';
        END IF;
        IF cardinality(audit_ids) > (
            SELECT count(*) FROM (
                SELECT 1 FROM audit_events WHERE id = ANY(audit_ids) FOR KEY SHARE
            ) AS locked
        ) THEN
            RAISE EXCEPTION 'flights refer to an audit event that does not exist'
                USING ERRCODE = 'foreign_key_violation';
        END IF;
        RETURN NULL;
    END $$
    """,
    "CREATE TRIGGER flights_references_inserted AFTER INSERT ON flights"
    " REFERENCING NEW TABLE AS new_flights FOR EACH STATEMENT"
    " EXECUTE FUNCTION flights_check_references()",
    "CREATE TRIGGER flights_references_updated AFTER UPDATE ON flights"
    " REFERENCING NEW TABLE AS new_flights FOR EACH STATEMENT"
    " EXECUTE FUNCTION flights_check_references()",
    """
    CREATE FUNCTION aircraft_delete_flights() RETURNS trigger LANGUAGE plpgsql AS $$
    BEGIN
        DELETE FROM flights WHERE aircraft_id IN (SELECT id FROM old_aircraft);
        RETURN NULL;
    END $$
    """,
    "CREATE TRIGGER aircraft_deleted_flights AFTER DELETE ON aircraft"
    " REFERENCING OLD TABLE AS old_aircraft FOR EACH STATEMENT"
    " EXECUTE FUNCTION aircraft_delete_flights()",
    """
    CREATE FUNCTION aircraft_keep_flown_id() RETURNS trigger LANGUAGE plpgsql AS $$
    BEGIN
        IF NEW.id <> OLD.id AND EXISTS (SELECT 1 FROM flights WHERE aircraft_id = OLD.id) THEN
            RAISE EXCEPTION 'aircraft % has flights: its id cannot change', OLD.id
                USING ERRCODE = 'foreign_key_violation';
        END IF;
        RETURN NEW;
    END $$
    """,
    "CREATE TRIGGER aircraft_flown_id_kept BEFORE UPDATE OF id ON aircraft"
    " FOR EACH ROW EXECUTE FUNCTION aircraft_keep_flown_id()",
    """
    CREATE FUNCTION audit_events_keep_flight_events() RETURNS trigger LANGUAGE plpgsql AS $$
    BEGIN
        IF (TG_OP = 'DELETE' OR NEW.id <> OLD.id)
           AND EXISTS (SELECT 1 FROM flights WHERE audit_id = OLD.id) THEN
            RAISE EXCEPTION 'audit event % stored flights: it cannot be removed', OLD.id
                USING ERRCODE = 'foreign_key_violation';
        END IF;
        RETURN CASE TG_OP WHEN 'DELETE' THEN OLD ELSE NEW END;
    END $$
    """,
    "CREATE TRIGGER audit_events_flight_events_kept BEFORE DELETE OR UPDATE OF id ON audit_events"
    " FOR EACH ROW EXECUTE FUNCTION audit_events_keep_flight_events()",
)
_POSTGRESQL_DROP = (
    "DROP TRIGGER audit_events_flight_events_kept ON audit_events",
    "DROP FUNCTION audit_events_keep_flight_events()",
    "DROP TRIGGER aircraft_flown_id_kept ON aircraft",
    "DROP FUNCTION aircraft_keep_flown_id()",
    "DROP TRIGGER aircraft_deleted_flights ON aircraft",
    "DROP FUNCTION aircraft_delete_flights()",
    "DROP TRIGGER flights_references_updated ON flights",
    "DROP TRIGGER flights_references_inserted ON flights",
    "DROP FUNCTION flights_check_references()",
)

# RAISE(ABORT, ...) fails the statement with SQLITE_CONSTRAINT, as a foreign key does.
_SQLITE_MISSING = """
    WHEN NOT EXISTS (SELECT 1 FROM aircraft WHERE id = NEW.aircraft_id)
      OR (NEW.audit_id IS NOT NULL
          AND NOT EXISTS (SELECT 1 FROM audit_events WHERE id = NEW.audit_id))
    BEGIN SELECT RAISE(ABORT, 'FOREIGN KEY constraint failed: flights refer to a missing
    aircraft or audit event'); END
"""
_SQLITE = (
    f"CREATE TRIGGER flights_references_inserted BEFORE INSERT ON flights {_SQLITE_MISSING}",
    "CREATE TRIGGER flights_references_updated BEFORE UPDATE OF aircraft_id, audit_id ON flights"
    f" {_SQLITE_MISSING}",
    "CREATE TRIGGER aircraft_deleted_flights AFTER DELETE ON aircraft"
    " BEGIN DELETE FROM flights WHERE aircraft_id = OLD.id; END",
    "CREATE TRIGGER aircraft_flown_id_kept BEFORE UPDATE OF id ON aircraft"
    " WHEN NEW.id <> OLD.id AND EXISTS (SELECT 1 FROM flights WHERE aircraft_id = OLD.id)"
    " BEGIN SELECT RAISE(ABORT, 'FOREIGN KEY constraint failed: aircraft has flights'); END",
    "CREATE TRIGGER audit_events_flight_events_deleted BEFORE DELETE ON audit_events"
    " WHEN EXISTS (SELECT 1 FROM flights WHERE audit_id = OLD.id)"
    " BEGIN SELECT RAISE(ABORT, 'FOREIGN KEY constraint failed: audit event stored flights');"
    " END",
    "CREATE TRIGGER audit_events_flight_events_renumbered BEFORE UPDATE OF id ON audit_events"
    " WHEN NEW.id <> OLD.id AND EXISTS (SELECT 1 FROM flights WHERE audit_id = OLD.id)"
    " BEGIN SELECT RAISE(ABORT, 'FOREIGN KEY constraint failed: audit event stored flights');"
    " END",
)
_SQLITE_DROP = (
    "DROP TRIGGER audit_events_flight_events_renumbered",
    "DROP TRIGGER audit_events_flight_events_deleted",
    "DROP TRIGGER aircraft_flown_id_kept",
    "DROP TRIGGER aircraft_deleted_flights",
    "DROP TRIGGER flights_references_updated",
    "DROP TRIGGER flights_references_inserted",
)


def upgrade() -> None:
    # SQLite drops the foreign keys by copying the table (batch mode) before any trigger exists.
    with op.batch_alter_table("flights") as batch:
        for name, _table, _column, _ondelete in _FKS:
            batch.drop_constraint(name, type_="foreignkey")
    postgresql = op.get_bind().dialect.name == "postgresql"
    for statement in _POSTGRESQL if postgresql else _SQLITE:
        op.execute(sa.text(statement))


def downgrade() -> None:
    postgresql = op.get_bind().dialect.name == "postgresql"
    for statement in _POSTGRESQL_DROP if postgresql else _SQLITE_DROP:
        op.execute(sa.text(statement))
    with op.batch_alter_table("flights") as batch:
        for name, table, column, ondelete in _FKS:
            batch.create_foreign_key(name, table, [column], ["id"], ondelete=ondelete)
