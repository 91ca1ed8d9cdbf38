"""Speed of the compiled march against a plain eager loop measured in the same run.

    .venv/bin/python -m benchmarks.speed            # readable table
    .venv/bin/python -m benchmarks.speed --json     # one JSON line

Workloads (thesis scale, hybrid MLP#1 kernel, float64, one thread):
  train epoch: 60 aircraft x 7,300 flights, 5 inspections each; forward + backward + Adam step.
  forecast:    300 aircraft x 7,300 flights, forward only, no grad.
Timings are CPU seconds of this (single-threaded) process, the fastest of several repeats: on
the shared development machine wall time mostly measures how long other processes held the
cores (wall-clock epoch speedups of one code version scattered between 55x and 150x).

max_rel_diff compares the fast and the sequential march (float64, trajectory and every
gradient of the epoch loss), as max |fast - sequential| / max |sequential| over tensors.
fit_peak_rss_mb is the process's peak resident memory after a default fit (model.train.fit,
L-BFGS) of the 60 aircraft, before any eager work (whose 7,300-step autograd graph would
dominate the peak); fit_s is that fit's CPU time.
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from collections.abc import Callable

import torch
from torch import Tensor

from model.cells import DamageKernel, MLPKernel
from model.hybrid import CrackGrowthModel, ModelSpec, default_box
from model.integrate import LoadHistory, Observations
from model.nets import THESIS_MLPS
from model.physics import ParisLaw
from model.runtime import configure_threads
from model.train import TrainConfig, fit

FLIGHTS = 7300
TRAIN_AIRCRAFT, FORECAST_AIRCRAFT = 60, 300
INSPECTIONS = 5
MISSIONS_MPA = (92.5, 100.0, 110.0, 130.0)


def synthetic_loads(aircraft: int, seed: int) -> LoadHistory:
    """Each aircraft flies a fixed share of two missions, with 3 % per-flight scatter."""
    gen = torch.Generator().manual_seed(seed)
    missions = torch.tensor(MISSIONS_MPA, dtype=torch.float64)
    pair = torch.randint(0, len(MISSIONS_MPA), (aircraft, 2), generator=gen)
    share = torch.rand(aircraft, 1, generator=gen, dtype=torch.float64)
    first = torch.rand(aircraft, FLIGHTS, generator=gen, dtype=torch.float64) < share
    stress = torch.where(first, missions[pair[:, :1]], missions[pair[:, 1:]])
    stress = stress * (1 + 0.03 * torch.randn(aircraft, FLIGHTS, generator=gen, dtype=stress.dtype))
    return LoadHistory(stress, torch.full((aircraft,), FLIGHTS))


def make_model(loads: LoadHistory) -> CrackGrowthModel:
    law = ParisLaw()
    spec = ModelSpec(
        kernel="mlp", hidden=THESIS_MLPS[1], law=law, box=default_box(loads.stress_range_mpa, law)
    )
    torch.manual_seed(0)
    model = CrackGrowthModel(spec)
    kernel = model.kernel
    assert isinstance(kernel, MLPKernel)
    last = kernel.mlp.linears[-1]
    assert isinstance(last, torch.nn.Linear)
    with torch.no_grad():  # start near physical growth rates instead of a random sign
        last.bias.fill_(0.5)
    return model


def inspections(loads: LoadHistory, seed: int) -> Observations:
    """Five inspections per aircraft at random flights, crack from the physics kernel + noise."""
    gen = torch.Generator().manual_seed(seed)
    aircraft = loads.lengths.shape[0]
    flights = torch.randint(1, FLIGHTS + 1, (aircraft, INSPECTIONS), generator=gen)
    physics = CrackGrowthModel(ModelSpec(kernel="physics"))
    with torch.no_grad():
        traj = physics.trajectory(loads)
    rows = torch.arange(aircraft).repeat_interleave(INSPECTIONS)
    true = traj[rows, flights.reshape(-1)]
    noisy = true * (1 + 0.02 * torch.randn(true.shape, generator=gen, dtype=true.dtype))
    return Observations(rows, flights.reshape(-1), noisy)


def eager_trajectory(kernel: DamageKernel, law: ParisLaw, loads: LoadHistory) -> Tensor:
    """The reference: one torch step per flight, a_t = a_{t-1} + C max(dK, 0)**m."""
    stress, mask = loads.stress_range_mpa, loads.mask
    crack = torch.full(stress.shape[:1], law.initial_crack_m, dtype=stress.dtype)
    states = [crack]
    for k in range(stress.shape[1]):
        grown = crack + law.c * kernel(stress[:, k], crack).clamp_min(0.0) ** law.m
        crack = torch.where(mask[:, k], grown, crack)
        states.append(crack)
    return torch.stack(states, dim=1)


def epoch_loss(traj: Tensor, obs: Observations) -> Tensor:
    predicted = traj[obs.aircraft, obs.flights]
    return ((predicted - obs.crack_length_m) / obs.crack_length_m).pow(2).mean()


def best_of(repeats: int, run: Callable[[], object]) -> float:
    """Fewest CPU seconds of `repeats` calls."""
    times = []
    for _ in range(repeats):
        start = time.process_time()
        run()
        times.append(time.process_time() - start)
    return min(times)


def relative_diff(fast: list[Tensor], reference: list[Tensor]) -> float:
    return max(
        float((f - r).abs().max() / r.abs().max().clamp_min(1e-300))
        for f, r in zip(fast, reference, strict=True)
    )


def values_and_grads(
    model: CrackGrowthModel, loads: LoadHistory, obs: Observations, method: str
) -> list[Tensor]:
    model.zero_grad()
    traj = model.trajectory(loads, method=method)
    epoch_loss(traj, obs).backward()
    return [traj.detach().to(torch.float64)] + [
        p.grad.detach().to(torch.float64) for p in model.parameters() if p.grad is not None
    ]


def run(repeats: int) -> dict[str, float]:
    configure_threads(1)
    loads = synthetic_loads(TRAIN_AIRCRAFT, seed=1)
    obs = inspections(loads, seed=2)
    model = make_model(loads)
    law = model.spec.law
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-3)

    def fast_epoch() -> None:
        optimizer.zero_grad()
        epoch_loss(model.trajectory(loads), obs).backward()
        optimizer.step()

    def eager_epoch() -> None:
        optimizer.zero_grad()
        epoch_loss(eager_trajectory(model.kernel, law, loads), obs).backward()
        optimizer.step()

    fast_epoch()  # loads (or compiles) the numba kernels
    fast_epoch_s = best_of(max(repeats, 20), fast_epoch)
    start = time.process_time()
    fit(make_model(loads), loads, obs, TrainConfig())  # the service's default fit
    fit_s = time.process_time() - start
    fit_peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    eager_epoch_s = best_of(repeats, eager_epoch)

    with torch.no_grad():
        fast_forward_s = best_of(max(repeats, 20), lambda: model.trajectory(loads))
    traj = model.trajectory(loads)
    params = list(model.parameters())
    backward_s = best_of(
        max(repeats, 20),
        lambda: torch.autograd.grad(epoch_loss(traj, obs), params, retain_graph=True),
    )

    fleet = synthetic_loads(FORECAST_AIRCRAFT, seed=3)
    with torch.no_grad():
        fast_forecast_s = best_of(max(repeats, 20), lambda: model.trajectory(fleet))
        eager_forecast_s = best_of(repeats, lambda: eager_trajectory(model.kernel, law, fleet))

    model64 = make_model(loads)  # fresh: the diff must not depend on how many steps were timed
    diff64 = relative_diff(
        values_and_grads(model64, loads, obs, "fast"),
        values_and_grads(model64, loads, obs, "sequential"),
    )
    model32 = make_model(loads).float()
    loads32 = loads.to(torch.float32)
    obs32 = Observations(obs.aircraft, obs.flights, obs.crack_length_m.float())
    diff32 = relative_diff(
        values_and_grads(model32, loads32, obs32, "fast"),
        values_and_grads(model32, loads32, obs32, "sequential"),
    )
    return {
        "train_epoch_speedup": eager_epoch_s / fast_epoch_s,
        "forecast_speedup": eager_forecast_s / fast_forecast_s,
        "max_rel_diff": diff64,
        "max_rel_diff_float32": diff32,
        "eager_epoch_s": eager_epoch_s,
        "fast_epoch_s": fast_epoch_s,
        "fast_forward_s": fast_forward_s,
        "fast_backward_s": backward_s,
        "eager_forecast_s": eager_forecast_s,
        "fast_forecast_s": fast_forecast_s,
        "fit_s": fit_s,
        "fit_peak_rss_mb": fit_peak_rss_mb,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON line")
    parser.add_argument("--repeats", type=int, default=3, help="repeats of each eager timing")
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    results = run(args.repeats)
    if args.json:
        print(json.dumps({k: float(f"{v:.6g}") for k, v in results.items()}))
        return
    r = results
    print(f"{'workload':<44}{'eager s':>9}{'fast s':>9}{'speedup':>9}  goal")
    for name, key in (
        (f"train epoch {TRAIN_AIRCRAFT} x {FLIGHTS:,} (fwd+bwd+Adam)", "epoch"),
        (f"forecast {FORECAST_AIRCRAFT} x {FLIGHTS:,} (no grad)", "forecast"),
    ):
        eager, fast = r[f"eager_{key}_s"], r[f"fast_{key}_s"]
        goal = ">= 30" if key == "epoch" else ">= 10"
        print(f"{name:<44}{eager:>9.3f}{fast:>9.4f}{eager / fast:>8.1f}x  {goal}")
    print(f"fast forward / backward, {TRAIN_AIRCRAFT} aircraft (s): ", end="")
    print(f"{r['fast_forward_s']:.4f} / {r['fast_backward_s']:.4f}")
    print(f"max rel diff fast vs sequential, float64: {r['max_rel_diff']:.2e}  (goal <= 1e-6)")
    print(f"max rel diff fast vs sequential, float32: {r['max_rel_diff_float32']:.2e}  (<= 1e-5)")
    print(f"default fit (L-BFGS) of {TRAIN_AIRCRAFT} aircraft: {r['fit_s']:.2f} s, ", end="")
    print(f"peak RSS {r['fit_peak_rss_mb']:.0f} MB  (goal < 2048)")
    print(f"peak RSS of the whole run (eager included): {r['peak_rss_mb']:.0f} MB")


if __name__ == "__main__":
    main()
