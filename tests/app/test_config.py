"""Settings fail fast on bad configuration, naming the setting; good values pass through."""

from typing import Any

import pytest
from pydantic import ValidationError

from app.config import Settings, get_settings


def _error(**values: Any) -> str:
    with pytest.raises(ValidationError) as failed:
        Settings(**values)
    return str(failed.value)


@pytest.mark.parametrize(
    ("values", "named"),
    [
        ({"database_url": "mysql://db/fleet"}, "sqlite:// or postgresql://"),
        ({"kernel": "lstm"}, "kernel must be one of"),
        ({"optimizer": "sgd"}, "optimizer must be one of"),
        ({"paris_c": 0}, "paris_c"),
        ({"holdout_fraction": 1.0}, "holdout_fraction"),
        ({"forecast_samples": 0}, "forecast_samples"),
        ({"forecast_samples": 5001}, "forecast_samples"),
        ({"worker_poll_seconds": 0}, "worker_poll_seconds"),
        ({"lbfgs_iterations": 10_001}, "lbfgs_iterations"),
        ({"epochs": 100_001}, "epochs"),
        ({"max_sampling_bytes": 1024}, "max_sampling_bytes"),
        ({"earliest_record_date": "soon"}, "earliest_record_date"),
    ],
)
def test_bad_values_are_rejected_naming_the_setting(values: dict[str, Any], named: str) -> None:
    assert named in _error(**values)


def test_the_law_needs_a_critical_crack_beyond_the_initial_one() -> None:
    message = _error(initial_crack_m=0.05, critical_crack_m=0.01)
    assert "critical_crack_m" in message


def test_good_values_pass_and_build_the_law() -> None:
    settings = Settings(
        database_url="postgresql://user@host/fleet",
        kernel="mlp",
        optimizer="adam",
        paris_c=2e-11,
        critical_crack_m=0.04,
    )
    law = settings.law()
    assert (settings.kernel, settings.optimizer) == ("mlp", "adam")
    assert (law.c, law.m, law.critical_crack_m) == (2e-11, 3.8, 0.04)


def test_settings_come_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FLEETPINN_KERNEL", "physics")
    monkeypatch.setenv("FLEETPINN_FORECAST_SAMPLES", "50")
    get_settings.cache_clear()
    try:
        settings = get_settings()
        assert (settings.kernel, settings.forecast_samples) == ("physics", 50)
        assert get_settings() is settings  # cached
        monkeypatch.setenv("FLEETPINN_KERNEL", "unknown")
        get_settings.cache_clear()
        with pytest.raises(ValidationError, match="kernel"):
            get_settings()
    finally:
        get_settings.cache_clear()
