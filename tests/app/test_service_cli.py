"""The service subcommands of `fleetpinn` against a SQLite file named by the environment."""

from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

from app.cli import main
from app.config import get_settings


@pytest.fixture
def database(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    path = tmp_path / "cli.db"
    monkeypatch.setenv("FLEETPINN_DATABASE_URL", f"sqlite:///{path}")
    get_settings.cache_clear()
    yield path
    get_settings.cache_clear()


def test_seed_retrain_and_export(
    database: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["migrate"]) == 0
    assert database.is_file()
    seed = ["seed-demo", "--aircraft-per-mix", "2", "--years", "1", "--inspected", "3"]
    assert main(seed) == 0
    assert '"inserted": 8760' in capsys.readouterr().out  # 6 aircraft x 1,460 flights
    assert main(seed) == 0
    assert '"duplicates": 8760' in capsys.readouterr().out
    assert main(["retrain", "--kernel", "physics"]) == 0
    assert '"model_version": 1' in capsys.readouterr().out
    out = tmp_path / "forecasts.parquet"
    assert main(["forecast-batch", "--out", str(out)]) == 0
    frame = pd.read_parquet(out)
    assert len(frame) == 6
    assert frame["rank"].tolist() == [1, 2, 3, 4, 5, 6]
    assert frame["flights_flown"].eq(1460).all()
    assert main(["worker", "--once"]) == 0
    assert "ran 0 job(s)" in capsys.readouterr().out


def test_forecast_batch_rejects_an_unknown_suffix(
    database: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["forecast-batch", "--out", "x.txt"]) == 2
    assert "--out must end in .csv, .parquet or .json" in capsys.readouterr().err


@pytest.mark.parametrize(
    "name, value, says",
    [
        ("FLEETPINN_SIZING_RELATIVE_SD", "-1", "FLEETPINN_SIZING_RELATIVE_SD"),
        ("FLEETPINN_KERNEL", "foo", "FLEETPINN_KERNEL"),
        ("FLEETPINN_THREADS", "x", "FLEETPINN_THREADS"),
    ],
)
def test_a_bad_setting_exits_2_with_one_line(
    database: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    name: str,
    value: str,
    says: str,
) -> None:
    monkeypatch.setenv(name, value)
    assert main(["migrate"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0] and err[0].startswith("fleetpinn migrate: error:")
    assert not database.exists()  # nothing was done


def test_serve_refuses_zero_processes(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["serve", "--processes", "0"]) == 2
    assert "--processes must be >= 1" in capsys.readouterr().err
