"""CrackGrowthModel shared between threads, as the service's model cache shares it."""

import threading

import torch

from model.hybrid import CrackGrowthModel, ModelSpec, default_box
from model.physics import ParisLaw
from model.uncertainty import flat_parameters


def test_trajectory_with_is_safe_from_concurrent_threads() -> None:
    """Each thread's march runs under its own weights and sees the model's parameters (a
    request and the worker marching posterior draws on one cached model at once)."""
    stress = 80.0 + 80.0 * torch.rand(
        6, 400, dtype=torch.float64, generator=torch.Generator().manual_seed(0)
    )
    lengths = torch.full((6,), 400)
    a0 = torch.full((6,), 0.005, dtype=torch.float64)
    law = ParisLaw()
    model = CrackGrowthModel(ModelSpec("residual", box=default_box(stress, law), law=law))
    base = flat_parameters(model)
    draws = [base + 0.05 * k for k in range(4)]
    with torch.no_grad():
        expected = [model.trajectory_with(w, stress, lengths, a0)[:, -1] for w in draws]
    errors: list[BaseException] = []
    wrong: list[int] = []

    def march(k: int) -> None:
        try:
            with torch.no_grad():
                for _ in range(60):
                    got = model.trajectory_with(draws[k], stress, lengths, a0)[:, -1]
                    if not torch.equal(got, expected[k]):
                        wrong.append(k)
        except BaseException as exc:  # collected: a thread's exception would be lost
            errors.append(exc)

    threads = [threading.Thread(target=march, args=(k,)) for k in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == [] and wrong == []
    assert torch.equal(flat_parameters(model), base)  # the model's own weights are back
