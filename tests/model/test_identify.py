"""Damping identification of the 2-DOF system by (robust) least squares through the RK4 march."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from model.cells import RungeKuttaCell, TwoDofDynamics
from model.identify import IdentifyConfig, ObservedMarch, identify
from model.robust_noise import noise_variance
from model.two_dof import (
    TABLE_3_1_BURSTS,
    TRAIN_COLUMNS,
    TRUE_DAMPING,
    Burst,
    contaminate,
    fit,
    prediction_rmse,
    random_bursts,
    read_two_dof_csv,
)

torch.set_num_threads(1)

DATA_DIR = Path(__file__).resolve().parents[2] / "data" / "two_dof"
# Least-squares optimum on data/two_dof/train.csv (Levenberg-Marquardt run to 1e-9 relative steps).
LS_OPTIMUM = (92.3724, 119.2131, 149.1437)
TRUTH = np.array(TRUE_DAMPING)


@pytest.fixture(scope="module")
def train() -> pd.DataFrame:
    if not (DATA_DIR / "train.csv").is_file():
        pytest.skip(f"shared 2-DOF data not found at {DATA_DIR}")
    return read_two_dof_csv(DATA_DIR / "train.csv", (*TRAIN_COLUMNS, "y0", "y1"))


@pytest.fixture(scope="module")
def held_out() -> pd.DataFrame:
    if not (DATA_DIR / "test.csv").is_file():
        pytest.skip(f"shared 2-DOF data not found at {DATA_DIR}")
    return read_two_dof_csv(DATA_DIR / "test.csv", ("t", "u0", "u1", "y0", "y1"))


def _arrays(frame: pd.DataFrame, steps: int | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    rows = len(frame) if steps is None else steps + 1
    forces = torch.tensor(frame[["u0", "u1"]].to_numpy()[: rows - 1]).unsqueeze(0)
    observed = torch.tensor(frame[["yT0", "yT1"]].to_numpy()[:rows]).unsqueeze(0)
    return forces, observed


@pytest.mark.parametrize("robust", [False, True], ids=["plain", "robust"])
def test_fit_reaches_the_least_squares_optimum_and_predicts_the_test_file(
    train: pd.DataFrame, held_out: pd.DataFrame, robust: bool
) -> None:
    # On Gaussian noise the robust fit detects no burst and keeps (nearly) uniform weights.
    fitted = fit(train, IdentifyConfig(robust=robust))
    c, sd = np.array(fitted["c"]), np.array(fitted["c_sd"])
    np.testing.assert_allclose(c, LS_OPTIMUM, rtol=5e-3)
    assert fitted["converged"]
    assert prediction_rmse(c, held_out) <= 1e-6
    # sigma^2 (J^T J)^-1 at the file's noise level (1.5e-5 m): c3 is the least identifiable.
    assert 5.0 < sd[0] < 8.0 and 7.0 < sd[1] < 12.0 and 18.0 < sd[2] < 30.0
    assert (np.abs(c - TRUTH) <= 1.96 * sd).all()


@pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning")
def test_complex_step_jacobian_equals_forward_mode_autograd(train: pd.DataFrame) -> None:
    forces, _ = _arrays(train, steps=40)
    cell = RungeKuttaCell(TwoDofDynamics((10.0, 10.0, 10.0)), 0.002)
    observed_march = ObservedMarch(cell, forces, torch.zeros(1, 4, dtype=torch.float64), (0, 1))
    theta = torch.tensor([90.0, 120.0, 150.0], dtype=torch.float64)
    value_c, jac_c = observed_march.value_and_jacobian(theta, "complex-step")
    value_f, jac_f = observed_march.value_and_jacobian(theta, "forward-mode")
    assert jac_c.shape == (1, 41, 2, 3)
    torch.testing.assert_close(value_c, value_f, rtol=1e-13, atol=1e-20)
    torch.testing.assert_close(jac_c, jac_f, rtol=1e-10, atol=1e-22)


def test_identify_leaves_the_cell_untouched_and_loads_back(train: pd.DataFrame) -> None:
    forces, observed = _arrays(train, steps=200)
    cell = RungeKuttaCell(TwoDofDynamics((10.0, 10.0, 10.0)), 0.002)
    result = identify(
        cell,
        forces,
        observed,
        torch.zeros(1, 4, dtype=torch.float64),
        (0, 1),
        IdentifyConfig(max_iterations=3, robust=False),
    )
    assert cell.rhs.damping.tolist() == [10.0, 10.0, 10.0]
    assert result.names == ("rhs.damping[0]", "rhs.damping[1]", "rhs.damping[2]")
    assert result.prediction.shape == observed.shape
    cell.load_state_dict(result.state_dict(cell), strict=False)
    assert cell.rhs.damping.tolist() == result.parameters.tolist()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"observed_states": (0,)}, "observed_states"),
        ({"observed_states": (0, 7)}, r"observed_states must lie"),
        ({"initial": torch.zeros(2, 4, dtype=torch.float64)}, "initial"),
    ],
)
def test_identify_rejects_inconsistent_shapes(
    train: pd.DataFrame, kwargs: dict[str, object], message: str
) -> None:
    forces, observed = _arrays(train, steps=20)
    arguments: dict[str, object] = {
        "cell": RungeKuttaCell(TwoDofDynamics((10.0, 10.0, 10.0)), 0.002),
        "inputs": forces,
        "observed": observed,
        "initial": torch.zeros(1, 4, dtype=torch.float64),
        "observed_states": (0, 1),
    }
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=message):
        identify(**arguments)  # type: ignore[arg-type]


def test_identify_config_rejects_unknown_options() -> None:
    with pytest.raises(ValueError, match="jacobian"):
        IdentifyConfig(jacobian="finite-difference")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="scale_window"):
        IdentifyConfig(scale_window=50)


def test_noise_variance_marks_bursts_to_the_sample_and_leaves_clean_noise_uniform() -> None:
    generator = torch.Generator().manual_seed(0)
    residual = torch.randn(1, 1001, 2, dtype=torch.float64, generator=generator)
    clean = noise_variance(residual, 51, 1e-4)
    assert torch.unique(clean[0, :, 0]).numel() == 1 and torch.unique(clean[0, :, 1]).numel() == 1
    residual[0, 300:350, 0] *= 20.0
    residual[0, 600:700, 1] *= 10.0
    variance = noise_variance(residual, 51, 1e-4)
    raised = variance > variance.amin(dim=1, keepdim=True)
    # To the sample, give or take the one clean neighbour whose second difference holds a burst
    # sample.
    for channel, (first, end) in enumerate(((300, 350), (600, 700))):
        marked = set(raised[0, :, channel].nonzero().flatten().tolist())
        assert set(range(first, end)) <= marked <= set(range(first - 1, end + 1))
    torch.testing.assert_close(
        variance.amin(dim=1).sqrt(), torch.ones(1, 2, dtype=torch.float64), rtol=0.05, atol=0
    )
    assert 10.0 < float(variance[0, 310:340, 0].sqrt().median()) < 25.0


def test_read_two_dof_csv_names_the_file_and_column(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    pd.DataFrame({"t": [0.0, 0.002, 0.004], "u0": [1.0, 1.0, 1.0], "u1": [0, 0, 0]}).to_csv(
        path, index=False
    )
    with pytest.raises(ValueError, match=r"bad\.csv: missing column 'yT0'"):
        read_two_dof_csv(path, TRAIN_COLUMNS)
    pd.DataFrame({"t": [0.0, 0.002, 0.004], "u0": [1.0, "x", 1.0]}).to_csv(path, index=False)
    with pytest.raises(ValueError, match=r"bad\.csv: column 'u0' must be finite"):
        read_two_dof_csv(path, ("t", "u0"))
    with pytest.raises(FileNotFoundError, match=r"missing\.csv"):
        read_two_dof_csv(tmp_path / "missing.csv", TRAIN_COLUMNS)


def _check_burst_fit(frame: pd.DataFrame, bursts: tuple[Burst, ...]) -> None:
    fitted = fit(frame)
    c, sd = np.array(fitted["c"]), np.array(fitted["c_sd"])
    assert fitted["converged"], bursts
    # Honest intervals: the truth lies inside estimate +- 1.96 sd.
    assert (np.abs(c - TRUTH) <= 1.96 * sd).all(), (c, sd, bursts)
    # The bursts cost some information, not most of it (clean-data sd about 6, 9, 23).
    assert (sd < np.array([12.0, 18.0, 45.0])).all(), (sd, bursts)


@pytest.mark.parametrize(
    ("name", "seed"), [("single_burst", 11), ("double_burst", 12)], ids=["single", "double"]
)
def test_robust_fit_copes_with_table_3_1_bursts(train: pd.DataFrame, name: str, seed: int) -> None:
    bursts = tuple(Burst(b.start_s, b.end_s, 40.0) for b in TABLE_3_1_BURSTS[name])
    _check_burst_fit(contaminate(train, bursts, seed=seed), bursts)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_robust_fit_copes_with_random_bursts(train: pd.DataFrame, seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    bursts = random_bursts(rng, 1 + seed % 2)
    _check_burst_fit(contaminate(train, bursts, seed=seed), bursts)


def test_goals_are_met_where_the_data_carry_the_information(train: pd.DataFrame) -> None:
    # At the file's noise (1.5e-5 m) the Cramer-Rao sd of c1, c2, c3 is 5.8, 8.5, 20.9 N s/m:
    # 5 %, 10 %, 15 % of the truth is under one sd for c1 and c3, so no estimator meets those
    # goals reliably there.  A third of the noise meets them, bursts included.
    bursts = (Burst(0.1, 0.2, 40.0), Burst(0.4, 0.5, 40.0))
    fitted = fit(contaminate(train, bursts, seed=21, noise_sd=5e-6))
    c, sd = np.array(fitted["c"]), np.array(fitted["c_sd"])
    assert (np.abs(c - TRUTH) <= np.array([0.05, 0.10, 0.15]) * TRUTH).all(), c
    assert (np.abs(c - TRUTH) <= 1.96 * sd).all(), (c, sd)
