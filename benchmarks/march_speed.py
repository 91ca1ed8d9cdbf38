"""The compiled march's speed on today's single-range input against a reference version of the
code, measured in the same run, and what a 10-cycle spectrum per flight costs.

    .venv/bin/python -m benchmarks.march_speed                      # against main
    .venv/bin/python -m benchmarks.march_speed --reference db9d730 --rounds 5 --json

The reference's model/ is taken from git (`git archive`) into a temporary directory; the same
workload script runs in that tree and in this one as alternating subprocesses (rounds), so both
meet the same machine load; each takes the least CPU time of its repeats and the table keeps
the least over rounds.  Workloads (residual MLP#1 kernel, float64, one thread, through
`CrackGrowthModel.trajectory`, the path every caller takes):
  forecast: 300 aircraft x 7,300 flights, forward, no grad;
  epoch:    60 aircraft x 7,300 flights, forward + backward of a sum of cracks;
  read:     300 aircraft x 7,300 flights, each read at its last flight (`at`), no grad (the
            refill's crack samples);
  joint:    one closure of the joint fit (model.tracking_fit): 240 rows x 5,840 flights twice as
            lanes, read at two flights each (`at`), backward to the weights and growth factors.
`same_bits` says whether both trees' forecast trajectories are equal bit for bit,
`same_gradient_bits` whether the joint closure's gradients are.  The spectrum
rows (this tree only): the same forecast from a history of 10 cycles per flight (Walker law),
its reduction to one range per flight (once per history and law) and the march after it.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

WORKLOAD = r"""
import hashlib, json, sys, time
import torch
torch.set_num_threads(1)
from model.hybrid import CrackGrowthModel, ModelSpec, default_box
from model.integrate import LoadHistory
from model.physics import ParisLaw

FLIGHTS = 7300
repeats = int(sys.argv[1])
spectra = sys.argv[2] == "1"

def loads(aircraft, seed):
    gen = torch.Generator().manual_seed(seed)
    missions = torch.tensor((92.5, 100.0, 110.0, 130.0), dtype=torch.float64)
    pick = torch.randint(0, 4, (aircraft, FLIGHTS), generator=gen)
    stress = missions[pick] * (1 + 0.03 * torch.randn(aircraft, FLIGHTS, generator=gen, dtype=torch.float64))
    return LoadHistory(stress, torch.full((aircraft,), FLIGHTS))

def model_for(history, growth_law="paris", law=None):
    law = law or ParisLaw()
    spec = ModelSpec(kernel="residual", law=law, box=default_box(history.stress_range_mpa, law))
    if growth_law != "paris":
        from dataclasses import replace
        spec = replace(spec, growth_law=growth_law)
    torch.manual_seed(0)
    model = CrackGrowthModel(spec)
    last = model.kernel.mlp.linears[-1]
    with torch.no_grad():
        last.weight.normal_(0.0, 0.1)
        last.bias.fill_(0.05)
    return model

def best(run):
    run()
    times = []
    for _ in range(repeats):
        start = time.process_time()
        run()
        times.append(time.process_time() - start)
    return min(times)

out = {}
fleet = loads(300, 1)
model = model_for(fleet)
with torch.no_grad():
    traj = model.trajectory(fleet)
out["checksum"] = hashlib.sha256(traj.numpy().tobytes()).hexdigest()
def forecast():
    with torch.no_grad():
        model.trajectory(fleet)
out["forecast_s"] = best(forecast)
train = loads(60, 2)
def epoch():
    model.zero_grad()
    model.trajectory(train).sum().backward()
out["epoch_s"] = best(epoch)
# the refill's crack samples: every tail read at its last flight, no gradient
ends = (torch.arange(300), fleet.lengths)
def read():
    with torch.no_grad():
        model(fleet.stress_range_mpa, fleet.lengths, torch.full((300,), 0.005, dtype=torch.float64), at=ends)
out["read_s"] = best(read)
# one closure of the joint fit (model.tracking_fit): 240 rows to 5,840 flights, each twice (at
# z and z + 0.01) as lanes, read at two inspections with a gradient to the weights and factors
rows = loads(240, 4)
stress = rows.stress_range_mpa[:, :5840].repeat(2, 1).contiguous()
lengths = torch.full((480,), 5840)
start = torch.full((480,), 0.005, dtype=torch.float64)
z = 0.25 * torch.randn(480, generator=torch.Generator().manual_seed(5), dtype=torch.float64)
lane = torch.arange(480).repeat_interleave(2)
flight = torch.tensor((2920, 5840)).repeat(480)
def joint():
    model.zero_grad()
    factor = torch.exp(z).requires_grad_(True)
    read = model(stress, lengths, start, factor, at=(lane, flight))
    torch.log(read).sum().backward()
    return factor.grad
grads = [joint(), *(p.grad for p in model.parameters())]
out["joint_checksum"] = hashlib.sha256(b"".join(g.numpy().tobytes() for g in grads)).hexdigest()
out["joint_s"] = best(joint)
if spectra:
    from model.growth_laws import CycleSpectrum
    gen = torch.Generator().manual_seed(3)
    shape = (300, FLIGHTS, 10)
    ranges = 20.0 + 40.0 * torch.rand(shape, generator=gen, dtype=torch.float64)
    ranges[..., 0] = fleet.stress_range_mpa
    ratio = -0.3 + torch.rand(shape, generator=gen, dtype=torch.float64)
    cycles = CycleSpectrum(ranges, ratio, torch.ones(shape, dtype=torch.float64))
    law = ParisLaw(gamma=0.6)
    start = time.process_time()
    history = LoadHistory.from_cycles(cycles, fleet.lengths, "walker", law.constants)
    out["spectrum_reduce_s"] = time.process_time() - start
    walker = model_for(history, "walker", law)
    def spectrum_forecast():
        with torch.no_grad():
            walker.trajectory(history)
    out["spectrum_forecast_s"] = best(spectrum_forecast)
print(json.dumps(out))
"""


def reference_tree(ref: str, into: Path) -> Path:
    """The reference version's model/ package, extracted from git."""
    archive = into / "ref.tar"
    with archive.open("wb") as handle:
        subprocess.run(["git", "archive", ref, "model"], cwd=ROOT, stdout=handle, check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(into / "tree", filter="data")
    return into / "tree"


def measure(tree: Path, repeats: int, spectra: bool) -> dict[str, float | str]:
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(tree))
    done = subprocess.run(
        [sys.executable, "-c", WORKLOAD, str(repeats), "1" if spectra else "0"],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    result: dict[str, float | str] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference", default="main", help="git ref of today's code")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        reference = reference_tree(args.reference, Path(tmp))
        rows: dict[str, list[dict[str, float | str]]] = {"reference": [], "this": []}
        for _ in range(args.rounds):
            rows["reference"].append(measure(reference, args.repeats, spectra=False))
            rows["this"].append(measure(ROOT, args.repeats, spectra=True))

    def least(side: str, key: str) -> float:
        return min(float(row[key]) for row in rows[side])

    summary = {
        "reference": args.reference,
        "same_bits": rows["reference"][0]["checksum"] == rows["this"][0]["checksum"],
        "same_gradient_bits": rows["reference"][0].get("joint_checksum")
        == rows["this"][0].get("joint_checksum"),
        "forecast_s": {
            "reference": least("reference", "forecast_s"),
            "this": least("this", "forecast_s"),
        },
        "epoch_s": {"reference": least("reference", "epoch_s"), "this": least("this", "epoch_s")},
        "read_s": {"reference": least("reference", "read_s"), "this": least("this", "read_s")},
        "joint_s": {"reference": least("reference", "joint_s"), "this": least("this", "joint_s")},
        "spectrum_forecast_s": least("this", "spectrum_forecast_s"),
        "spectrum_reduce_s": least("this", "spectrum_reduce_s"),
    }
    for key in ("forecast_s", "epoch_s", "read_s", "joint_s"):
        pair = summary[key]
        assert isinstance(pair, dict)
        pair["ratio"] = pair["this"] / pair["reference"]
    if args.json:
        print(json.dumps(summary))
        return
    print(
        f"reference {args.reference}; trajectories equal bit for bit: {summary['same_bits']}; "
        f"the joint fit's gradients: {summary['same_gradient_bits']}"
    )
    for key in ("forecast_s", "epoch_s", "read_s", "joint_s"):
        pair = summary[key]
        assert isinstance(pair, dict)
        print(
            f"{key:10s} reference {pair['reference']:.4f} s  this {pair['this']:.4f} s  ratio {pair['ratio']:.3f}"
        )
    print(
        f"10-cycle spectrum: reduction {summary['spectrum_reduce_s']:.3f} s once, "
        f"forecast {summary['spectrum_forecast_s']:.4f} s"
    )


if __name__ == "__main__":
    main()
