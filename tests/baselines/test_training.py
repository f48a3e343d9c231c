"""Training on a tiny synthetic corpus through ClipDataset: inputs, one step of each model, checkpoint resume."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from baselines.data import load_or_extract
from baselines.features import ADMLP_INPUT_DIM, PoseHistory, admlp_input, tcp_state
from baselines.models import ADMLP, TCPConfig, TCPSmall
from baselines.train import TrainConfig, admlp_loss, is_best, load_checkpoint, tcp_loss, train


@pytest.fixture(scope="module")
def admlp_data(corpus: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, torch.Tensor]:
    return load_or_extract(corpus, "admlp", "all", 6, tmp_path_factory.mktemp("admlp_cache"))


@pytest.fixture(scope="module")
def tcp_data(corpus: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, torch.Tensor]:
    return load_or_extract(corpus, "tcp", "all", 4, tmp_path_factory.mktemp("tcp_cache"), (36, 64))


def test_admlp_inputs_from_the_loader(admlp_data: dict[str, torch.Tensor]) -> None:
    # Clip 1 drives straight at 5 m/s: frame 10's history is frames 0, 0, 0, 5 (the clip starts at frame 0, which
    # repeats), i.e. x = −5, −5, −5, −2.5 m in its own frame; the future is 2.5, 5, 7.5 m, then past the clip's end.
    x = admlp_data["input"][10]
    assert x.shape == (ADMLP_INPUT_DIM,)
    assert x[0:8:2].tolist() == pytest.approx([-5.0, -5.0, -5.0, -2.5], abs=1e-4)
    assert x[1:8:2].tolist() == pytest.approx([0.0] * 4, abs=1e-4)
    assert float(x[12]) == pytest.approx(5.0)  # speed
    assert x[16:].tolist() == [0, 0, 0, 1, 0, 0]  # next_command 4 = LANEFOLLOW → index 3
    assert admlp_data["future_wp"][10, :3, 0].tolist() == pytest.approx([2.5, 5.0, 7.5], abs=1e-4)
    assert admlp_data["future_valid"][10].tolist() == [True, True, True, False, False, False]
    # The agent-side builder gives the same vector from the same values.
    again = admlp_input(x[:8].numpy().reshape(4, 2), x[8:12].numpy(), 5.0, x[13:16].numpy(), 4)
    np.testing.assert_allclose(again, x.numpy(), atol=1e-6)


def test_pose_history_matches_the_clip_history() -> None:
    # 20 Hz ticks driving +x at 5 m/s: after 1 s (21 poses) the history at 0.5 s steps is −2 s, −1.5 s (both
    # before the start: the first pose repeats, −5 m), −1 s (−5 m) and −0.5 s (−2.5 m).
    h = PoseHistory(0.05)
    for k in range(21):
        h.append(0.25 * k, 0.0, 0.0)
    xy, yaw = h.past()
    assert xy[:, 0].tolist() == pytest.approx([-5.0, -5.0, -5.0, -2.5])
    assert yaw.tolist() == pytest.approx([0.0] * 4)


def test_tcp_state_layout() -> None:
    s = tcp_state(6.0, (10.0, -2.0), 1)  # LEFT → index 0
    assert s.tolist() == pytest.approx([0.5, 10.0, -2.0, 1, 0, 0, 0, 0, 0])


def _steps(model: torch.nn.Module, loss_fn, batch: dict[str, torch.Tensor], n: int, lr: float) -> list[float]:
    opt = torch.optim.Adam(model.parameters(), lr=lr)
    losses = []
    for _ in range(n):
        loss = loss_fn(model, batch)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    return losses


def test_admlp_steps_reduce_loss_and_shapes(admlp_data: dict[str, torch.Tensor]) -> None:
    torch.manual_seed(0)
    model = ADMLP()
    assert model(admlp_data["input"][:5]).shape == (5, 6, 3)
    losses = _steps(model, admlp_loss, admlp_data, 10, 1e-3)
    assert losses[-1] < 0.8 * losses[0]


def test_tcp_steps_reduce_loss_and_shapes(tcp_data: dict[str, torch.Tensor]) -> None:
    torch.manual_seed(0)
    model = TCPSmall(TCPConfig(image_height=36, image_width=64, feature_dim=int(tcp_data["feature"].shape[1]),
                               channels=(8, 16, 16, 32), hidden=64, attention_grid=(2, 4)))  # fmt: skip
    batch = {k: v[:16] for k, v in tcp_data.items() if k != "camera_hw"}
    out = model(batch["images"], batch["state"], batch["target_point"])
    assert out["pred_wp"].shape == (16, 4, 2)
    assert out["action_logits"].shape == (16, 39)
    assert tcp_data["camera_hw"].tolist() == [36, 64]  # the synthetic clips' camera size
    losses = _steps(model, tcp_loss, batch, 8, 1e-3)
    assert losses[-1] < losses[0]


def test_checkpoint_resume_restores_the_epoch(corpus: Path, tmp_path: Path) -> None:
    data = tmp_path / "corpus"
    shutil.copytree(corpus, data, ignore=shutil.ignore_patterns(".b2d_index"))
    out = tmp_path / "run"
    cfg = TrainConfig(model="admlp", data=data, out=out, epochs=2, batch_size=32)
    first = train(cfg)
    assert first["epoch"] == 2 and (out / "loss.png").is_file() and (out / "epoch_002.pt").is_file()
    cfg.epochs = 3
    resumed = train(cfg, resume=True)
    # Epochs 1–2 come back from last.pt (history kept), only epoch 3 is trained.
    assert resumed["epoch"] == 3
    assert [h["epoch"] for h in resumed["history"]] == [1.0, 2.0, 3.0]
    assert resumed["history"][:2] == first["history"]
    model, ckpt = load_checkpoint(out / "last.pt")
    assert ckpt["epoch"] == 3 and isinstance(model, ADMLP)


def test_best_epoch_is_the_lowest_val_loss_so_far() -> None:
    # val 2.4, 2.2, 2.3 (the TCP curve of the GPU run rose after its 4th epoch): epochs 1 and 2 each improve on what
    # came before, epoch 3 does not; a tie keeps the later epoch; without validation no epoch is "best".
    history = [{"epoch": 1.0, "val": 2.4}, {"epoch": 2.0, "val": 2.2}, {"epoch": 3.0, "val": 2.3}]
    assert [is_best(history[: k + 1]) for k in range(3)] == [True, True, False]
    assert is_best([*history, {"epoch": 4.0, "val": 2.2}])
    assert not is_best([{"epoch": 1.0, "train": 1.0}])
