"""fit(): train a crack model on crack observations at a few flights, back-propagating through
the whole load history.

Defaults are chosen by measurement: one L-BFGS call (strong-Wolfe line search) fits the hybrid
model far more accurately than 100 epochs of a first-order optimizer on this full-batch,
few-parameter problem; RMSprop and Adam remain available (the thesis used Adam/Adamax).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import torch
from torch import Tensor

from model.hybrid import CrackGrowthModel, ModelSpec, default_box
from model.integrate import LoadHistory, Observations, detection_scale
from model.nets import THESIS_MLPS, SequenceBaseline
from model.physics import ParisLaw, stress_intensity_range
from model.runtime import configure_threads

OPTIMIZERS = ("lbfgs", "rmsprop", "adam")
LOSSES = ("relative", "mse")
DEFAULT_LEARNING_RATE = {"lbfgs": 1.0, "rmsprop": 1e-3, "adam": 1e-3}


@dataclass(frozen=True)
class TrainConfig:
    """How to fit.  `epochs` counts first-order steps; L-BFGS runs one call of `lbfgs_iterations`.

    loss "relative" is the mean squared relative error (a_pred / a_obs - 1)**2, which weighs small
    and large cracks alike; "mse" is the thesis's plain mean squared error in m**2.
    threads: torch threads while fitting; None = the process setting (FLEETPINN_THREADS, else 1).
    measurement_sd: sd of a measured crack's log (relative measurement noise); it weighs
    non-detections against measured cracks (see `observation_loss`) and is unused without them.
    """

    optimizer: str = "lbfgs"
    epochs: int = 100
    lbfgs_iterations: int = 60
    learning_rate: float | None = None
    loss: str = "relative"
    seed: int = 0
    patience: int = 20
    min_improvement: float = 1e-4
    threads: int | None = None
    measurement_sd: float = 0.02

    def __post_init__(self) -> None:
        if self.optimizer not in OPTIMIZERS:
            raise ValueError(f"optimizer must be one of {OPTIMIZERS}, got {self.optimizer!r}")
        if self.loss not in LOSSES:
            raise ValueError(f"loss must be one of {LOSSES}, got {self.loss!r}")
        for name in ("epochs", "lbfgs_iterations", "patience"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.learning_rate is not None and not self.learning_rate > 0:
            raise ValueError(f"learning_rate must be > 0, got {self.learning_rate}")
        if not self.measurement_sd > 0:
            raise ValueError(f"measurement_sd must be > 0, got {self.measurement_sd}")

    @property
    def lr(self) -> float:
        return self.learning_rate or DEFAULT_LEARNING_RATE[self.optimizer]


@dataclass
class FitResult:
    """What a fit did: loss at each optimizer step (or L-BFGS evaluation), the loss of the weights
    returned (first-order fits return their best epoch), time, and whether it stopped early."""

    loss_history: list[float] = field(default_factory=list)
    final_loss: float = math.nan
    seconds: float = 0.0
    stopped_early: bool = False


def non_detection_nll(
    predicted_m: Tensor, a50_m: Tensor, a90_m: Tensor | None, measurement_sd: float | Tensor
) -> Tensor:
    """-log P(not detected | a) for each predicted crack a (m), elementwise.

    PoD(a) = Phi((ln a - ln a50) / s) with s = (ln a90 - ln a50) / Z90 (s = 0: a hard threshold
    at a50), seen through the log-normal measurement noise sd, so
    P(not detected | a) = Phi((ln a50 - ln a) / sqrt(s**2 + measurement_sd**2)): smooth even for
    a hard threshold.
    """
    scale = detection_scale(a50_m, a90_m, measurement_sd)
    return -torch.special.log_ndtr((torch.log(a50_m) - torch.log(predicted_m)) / scale)


def observation_loss(
    predicted: Tensor,
    observed: Tensor | Observations,
    kind: str,
    measurement_sd: float = TrainConfig.measurement_sd,
) -> Tensor:
    """Loss over the observed steps only (no crack data elsewhere).

    Measured cracks: "relative" = mean (a_pred / a_obs - 1)**2, "mse" = mean (a_pred - a_obs)**2.
    With non-detections (Observations with `detected`), "relative" reads the squared relative
    error as the Gaussian negative log-likelihood of ln a_obs with sd sigma = measurement_sd,
    times 2 sigma**2, and adds the non-detections on the same scale:

        loss = (sum_measured (a_pred / a_obs - 1)**2
                + 2 sigma**2 sum_missed -log P(not detected | a_pred)) / observations

    so a non-detection is neither ignored nor read as a zero crack.  Without non-detections the
    loss is exactly the plain one.  Raises ValueError for non-detections with kind "mse".
    """
    if isinstance(observed, Observations):
        obs = observed
        if obs.censored:
            if kind != "relative":
                raise ValueError("loss: non-detections need loss='relative'")
            assert obs.detected is not None and obs.detection_a50_m is not None
            hit, missed = obs.detected, ~obs.detected
            a90 = None if obs.detection_a90_m is None else obs.detection_a90_m[missed]
            measured = ((predicted[hit] / obs.crack_length_m[hit] - 1.0) ** 2).sum()
            nll = non_detection_nll(
                predicted[missed], obs.detection_a50_m[missed], a90, measurement_sd
            )
            return (measured + 2.0 * measurement_sd**2 * nll.sum()) / len(predicted)
        observed = obs.crack_length_m
    if kind == "relative":
        return ((predicted / observed - 1.0) ** 2).mean()
    return ((predicted - observed) ** 2).mean()


def _as_float64(observations: Observations, aircraft: Tensor) -> Observations:
    """Observations re-indexed to `aircraft`, with float64 crack lengths and thresholds."""

    def f64(values: Tensor | None) -> Tensor | None:
        return None if values is None else values.double()

    return Observations(
        aircraft,
        observations.flights,
        observations.crack_length_m.double(),
        observations.detected,
        f64(observations.detection_a50_m),
        f64(observations.detection_a90_m),
    )


def fit(
    model: CrackGrowthModel,
    loads: LoadHistory,
    observations: Observations,
    config: TrainConfig | None = None,
    progress: Callable[[float], None] | None = None,
) -> FitResult:
    """Fit `model` in place to crack observations; full batch over every observed aircraft.

    Only aircraft with an observation are marched.  `progress` receives a fraction in [0, 1].
    Raises ValueError when there is no observation or the model has nothing to learn.
    """
    config = config or TrainConfig()
    if len(observations.aircraft) == 0:
        raise ValueError("observations: at least one crack measurement is needed to train")
    params = [p for p in model.parameters() if p.requires_grad]
    if not params:
        raise ValueError(f"kernel {model.spec.kernel!r} has no parameter to train")
    configure_threads(config.threads)
    torch.manual_seed(config.seed)

    used, local_index = torch.unique(observations.aircraft, return_inverse=True)
    sub_loads = loads.select(used).to(torch.float64)
    sub_obs = _as_float64(observations, local_index)
    if sub_obs.censored and config.loss != "relative":
        raise ValueError("observations: non-detections need TrainConfig(loss='relative')")
    if int((sub_obs.flights > sub_loads.lengths[local_index]).sum()) > 0:
        raise ValueError("observations: an observation lies after its aircraft's last flight")

    def loss_now() -> Tensor:
        return observation_loss(
            model.at(sub_loads, sub_obs), sub_obs, config.loss, config.measurement_sd
        )

    result = FitResult()
    started = time.perf_counter()
    if config.optimizer == "lbfgs":
        minimize_lbfgs(params, loss_now, config, result, progress)
    else:
        _fit_first_order(model, params, loss_now, config, result, progress)
    with torch.no_grad():
        result.final_loss = float(loss_now())
    result.seconds = time.perf_counter() - started
    if progress is not None:
        progress(1.0)
    return result


def minimize_lbfgs(
    params: Sequence[Tensor],
    loss_now: Callable[[], Tensor],
    config: TrainConfig,
    result: FitResult,
    progress: Callable[[float], None] | None = None,
) -> None:
    """One L-BFGS call (strong Wolfe) of config.lbfgs_iterations on loss_now over params,
    recording each evaluation's loss in result.loss_history."""
    optimizer = torch.optim.LBFGS(
        params,
        lr=config.lr,
        max_iter=config.lbfgs_iterations,
        max_eval=config.lbfgs_iterations * 2,
        tolerance_grad=1e-12,
        tolerance_change=1e-14,
        history_size=20,
        line_search_fn="strong_wolfe",
    )

    def closure() -> Tensor:
        optimizer.zero_grad()
        loss = loss_now()
        loss.backward()
        result.loss_history.append(float(loss.detach()))
        if progress is not None:
            progress(min(len(result.loss_history) / (2 * config.lbfgs_iterations), 0.99))
        return loss

    optimizer.step(closure)


def _fit_first_order(
    model: torch.nn.Module,
    params: list[torch.nn.Parameter],
    loss_now: Callable[[], Tensor],
    config: TrainConfig,
    result: FitResult,
    progress: Callable[[float], None] | None,
) -> None:
    optimizer: torch.optim.Optimizer
    if config.optimizer == "rmsprop":
        optimizer = torch.optim.RMSprop(params, lr=config.lr)
    else:
        optimizer = torch.optim.Adam(params, lr=config.lr)
    best_loss, best_state, since_best = math.inf, None, 0
    for epoch in range(config.epochs):
        optimizer.zero_grad()
        loss = loss_now()
        value = float(loss.detach())
        result.loss_history.append(value)
        if value < best_loss * (1.0 - config.min_improvement):
            # the weights that produced this loss, taken before the step moves them
            best_loss, since_best = value, 0
            best_state = {k: v.detach().clone() for k, v in model.state_dict().items()}
        else:
            since_best += 1
        loss.backward()
        optimizer.step()
        if progress is not None:
            progress(min((epoch + 1) / config.epochs, 0.99))
        if since_best >= config.patience:
            result.stopped_early = True
            break
    if best_state is not None:
        model.load_state_dict(best_state)


def warm_start(model: CrackGrowthModel, points_per_axis: int = 24, iterations: int = 200) -> None:
    """Pre-fit a kernel that replaces dK to the physics dK over its input box (thesis practice).

    A residual kernel needs none: it starts at the physics by construction (zero correction).
    """
    if model.spec.kernel != "mlp":
        return
    box = model.spec.box
    assert box is not None
    law = model.spec.law
    stress = torch.linspace(*box.stress_range_mpa, points_per_axis, dtype=torch.float64)
    crack = torch.linspace(*box.crack_length_m, points_per_axis, dtype=torch.float64)
    grid_s, grid_a = torch.meshgrid(stress, crack, indexing="ij")
    target = stress_intensity_range(grid_s, grid_a, law.geometry)
    kernel = model.kernel
    optimizer = torch.optim.LBFGS(
        list(kernel.parameters()), max_iter=iterations, line_search_fn="strong_wolfe"
    )

    def closure() -> Tensor:
        optimizer.zero_grad()
        loss = (((kernel(grid_s, grid_a) - target) / target) ** 2).mean()
        loss.backward()
        return loss

    optimizer.step(closure)


def build_crack_model(
    loads: LoadHistory,
    *,
    kernel: str = "residual",
    hidden: tuple[tuple[int, str], ...] = THESIS_MLPS[1],
    law: ParisLaw | None = None,
    seed: int = 0,
    observations: Observations | None = None,
    growth_law: str = "paris",
) -> CrackGrowthModel:
    """A model over the fleet's input box (hybrid.default_box: cracks up to the longest
    measured in `observations` where given; ranges as the law reduces the flights) with its
    initial weights from `seed`, warm-started on the physics (a residual kernel starts there by
    construction); not yet fitted."""
    law = law or ParisLaw()
    stress = loads.for_law(growth_law, law.constants).stress_range_mpa
    box = None if kernel == "physics" else default_box(stress, law, observations)
    spec = ModelSpec(kernel=kernel, hidden=hidden, law=law, box=box, growth_law=growth_law)
    model = CrackGrowthModel(spec, seed)
    if kernel != "physics":
        warm_start(model)
    return model


def fit_crack_model(
    loads: LoadHistory,
    observations: Observations,
    *,
    kernel: str = "residual",
    hidden: tuple[tuple[int, str], ...] = THESIS_MLPS[1],
    law: ParisLaw | None = None,
    config: TrainConfig | None = None,
    progress: Callable[[float], None] | None = None,
) -> tuple[CrackGrowthModel, FitResult]:
    """Build a model over the fleet's input box, warm-start it, and fit it to the observations."""
    config = config or TrainConfig()
    model = build_crack_model(
        loads, kernel=kernel, hidden=hidden, law=law, seed=config.seed, observations=observations
    )
    if kernel == "physics":
        return model, FitResult()
    return model, fit(model, loads, observations, config, progress)


def fit_sequence_baseline(
    loads: LoadHistory,
    observations: Observations,
    *,
    kind: str,
    layers: int,
    units: int,
    law: ParisLaw | None = None,
    config: TrainConfig | None = None,
    progress: Callable[[float], None] | None = None,
) -> tuple[SequenceBaseline, FitResult]:
    """Train a purely data-driven LSTM/GRU (thesis Table 4.3) on the same observations.

    The network reads the stress history and emits a crack length after every flight; the loss
    sees only observed flights (>= 1), as for the hybrid model.  First-order optimizers only.
    """
    config = config or TrainConfig(optimizer="adam", epochs=200)
    if config.optimizer == "lbfgs":
        raise ValueError("optimizer: sequence baselines train with 'adam' or 'rmsprop'")
    if len(observations.aircraft) == 0 or int(observations.flights.min()) < 1:
        raise ValueError("observations: need at least one, each after >= 1 flight")
    law = law or ParisLaw()
    configure_threads(config.threads)
    torch.manual_seed(config.seed)
    box = default_box(loads.stress_range_mpa, law)
    net = SequenceBaseline(kind, layers, units, box.stress_range_mpa, law.initial_crack_m).double()
    used, local = torch.unique(observations.aircraft, return_inverse=True)
    sub = loads.select(used).to(torch.float64)
    observed = observations.crack_length_m.double()

    def loss_now() -> Tensor:
        predicted = net(sub.stress_range_mpa)[local, observations.flights - 1]
        return observation_loss(predicted, observed, config.loss)

    result = FitResult()
    started = time.perf_counter()
    _fit_first_order(net, list(net.parameters()), loss_now, config, result, progress)
    with torch.no_grad():
        result.final_loss = float(loss_now())
    result.seconds = time.perf_counter() - started
    return net, result
