import io

import pytest
import torch

from model import artifacts
from model.hybrid import CrackGrowthModel, ModelSpec, default_box
from model.integrate import LoadHistory
from model.nets import THESIS_MLPS
from model.physics import ParisLaw


@pytest.mark.parametrize("kernel", ["physics", "mlp", "residual"])
def test_round_trip_restores_predictions_and_metrics(tmp_path, kernel):
    loads = LoadHistory.from_sequences([[100.0] * 50, [130.0] * 30])
    law = ParisLaw(c=2e-11)
    box = None if kernel == "physics" else default_box(loads.stress_range_mpa, law)
    model = CrackGrowthModel(ModelSpec(kernel=kernel, hidden=THESIS_MLPS[3], law=law, box=box))
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.05)
    path = tmp_path / "model.pt"
    artifacts.save(model, path, {"val_median_abs_pct": 0.4})
    restored, metrics = artifacts.load(path)
    assert restored.spec == model.spec
    assert metrics == {"val_median_abs_pct": 0.4}
    with torch.no_grad():
        assert torch.equal(restored.final_crack(loads), model.final_crack(loads))


def test_newer_format_version_fails_clearly():
    buffer = io.BytesIO()
    torch.save({"format_version": artifacts.FORMAT_VERSION + 1}, buffer)
    with pytest.raises(ValueError, match="newer"):
        artifacts.from_bytes(buffer.getvalue())


def test_garbage_is_not_a_model():
    with pytest.raises(ValueError, match="not a fleetpinn model"):
        artifacts.from_bytes(b"hello")
