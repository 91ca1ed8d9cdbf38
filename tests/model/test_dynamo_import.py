"""An L-BFGS fit without importing torch._dynamo, to the same bits (a fresh process each: the
import is once per process)."""

import subprocess
import sys

_FIT = """
import sys, torch
if sys.argv[1] == "skip":
    from model.dynamo_import import skip_dynamo_import
    skip_dynamo_import()
torch.manual_seed(0)
x = torch.randn(6, dtype=torch.float64, requires_grad=True)
target = torch.linspace(-1.0, 2.0, 6, dtype=torch.float64)
opt = torch.optim.LBFGS([x], max_iter=30, line_search_fn="strong_wolfe")
def closure():
    opt.zero_grad()
    loss = ((x - target) ** 4).sum() + (x**2).sum()
    loss.backward()
    return loss
opt.step(closure)
print("torch._dynamo" in sys.modules, x.detach().numpy().tobytes().hex())
"""


def _fit(mode: str) -> tuple[str, str]:
    done = subprocess.run(
        [sys.executable, "-c", _FIT, mode], capture_output=True, text=True, check=True
    )
    imported, bits = done.stdout.split()
    return imported, bits


def test_lbfgs_runs_without_dynamo_to_the_same_bits() -> None:
    imported, bits = _fit("plain")
    assert imported == "True"  # what the skip saves: torch imports it here
    skipped, skipped_bits = _fit("skip")
    assert skipped == "False"
    assert skipped_bits == bits
