"""Train AD-MLP or the TCP-style model on a b2d-data corpus: checkpoint every epoch, ``--resume``, loss curve PNG.

    python -m baselines.train --model admlp --data corpus/ --out runs/admlp --epochs 20
    python -m baselines.train --model tcp --data corpus/ --out runs/tcp --epochs 30 --device cuda --time-budget 500

``--time-budget S`` stops before an epoch that would end past S seconds; run the same command with ``--resume`` to
continue (it also reuses the cached training tensors). ``runs/<model>/best.pt`` (lowest val loss; written when the corpus has a val split) or else ``last.pt`` is what
the chain's agents load.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F

from baselines.data import CAMERA_HW, has_split, load_or_extract
from baselines.models import ADMLP, ADMLPConfig, TCPConfig, TCPSmall

logger = logging.getLogger("baselines.train")

#: TCP's loss weights (Bench2DriveZoo TCP/config.py): speed 0.05, features 0.05.
SPEED_WEIGHT = 0.05
FEATURE_WEIGHT = 0.05


@dataclass
class TrainConfig:
    """What one training run does."""

    model: str
    data: Path
    out: Path
    epochs: int = 20
    batch_size: int = 256
    lr: float = 1e-3
    weight_decay: float = 1e-6
    device: str = "auto"
    image_size: tuple[int, int] = (144, 256)  # (height, width) of the TCP input
    workers: int = 0
    seed: int = 0
    time_budget: float | None = None
    curve: Path | None = None
    extra: dict[str, Any] = field(default_factory=dict)


def pick_device(name: str) -> torch.device:
    """``auto`` → cuda when available, else cpu."""
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    return torch.device(name)


def masked_l1(pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """Mean |pred − target| over valid waypoints (``valid`` (B, K); pred/target (B, K) or (B, K, D))."""
    err = (pred - target).abs()
    if err.dim() == 3:
        err = err.mean(dim=2)
    w = valid.float()
    return (err * w).sum() / w.sum().clamp(min=1.0)


def admlp_loss(model: ADMLP, batch: dict[str, torch.Tensor]) -> torch.Tensor:
    """L1 on future (x, y) plus L1 on future yaw, invalid (past the clip's end) waypoints masked out."""
    pred = model(batch["input"])
    return masked_l1(pred[..., :2], batch["future_wp"], batch["future_valid"]) + masked_l1(
        pred[..., 2], batch["future_yaw"], batch["future_valid"]
    )


def tcp_loss(model: TCPSmall, batch: dict[str, torch.Tensor]) -> torch.Tensor:
    """TCP's objective: waypoint L1 + expert-action cross-entropy + 0.05 speed L1 (+ 0.05 feature MSE)."""
    pred = model(batch["images"], batch["state"], batch["target_point"])
    loss = masked_l1(pred["pred_wp"], batch["future_wp"], batch["future_valid"])
    loss = loss + F.cross_entropy(pred["action_logits"].float(), batch["action"])
    loss = loss + SPEED_WEIGHT * F.l1_loss(pred["pred_speed"].float(), batch["speed"] / 12.0)
    if "feature_traj" in pred:
        feature = batch["feature"]
        loss = loss + FEATURE_WEIGHT * (
            F.mse_loss(pred["feature_traj"].float(), feature) + F.mse_loss(pred["feature_ctrl"].float(), feature)
        )
    return loss


def build_model(kind: str, config: dict[str, Any]) -> torch.nn.Module:
    """A model from its kind and checkpointed config dict."""
    if kind == "admlp":
        return ADMLP(ADMLPConfig(**config))
    if kind == "tcp":
        return TCPSmall(TCPConfig.from_dict(config))
    raise ValueError(f"unknown model {kind!r}")


def load_checkpoint(path: str | Path, device: str | torch.device = "cpu") -> tuple[torch.nn.Module, dict[str, Any]]:
    """The trained model (eval mode) and the checkpoint dict of ``path`` (``last.pt`` of a run)."""
    ckpt = torch.load(Path(path), map_location=device, weights_only=False)
    model = build_model(ckpt["kind"], ckpt["model_config"])
    model.load_state_dict(ckpt["model"])
    return model.to(device).eval(), ckpt


def _batches(data: dict[str, torch.Tensor], batch_size: int, shuffle: bool, gen: torch.Generator | None):
    n = len(data["speed"])
    order = torch.randperm(n, generator=gen) if shuffle else torch.arange(n)
    for i in range(0, n, batch_size):
        idx = order[i : i + batch_size]
        if shuffle and len(idx) < 2:
            continue  # a batch of one breaks batch norm
        yield {k: v[idx.to(v.device)] for k, v in data.items()}


def plot_curve(history: list[dict[str, float]], path: Path, title: str) -> None:
    """Loss per epoch (train, and val when present) as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    epochs = [h["epoch"] for h in history]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(epochs, [h["train"] for h in history], marker="o", label="train")
    if any("val" in h for h in history):
        ax.plot([h["epoch"] for h in history if "val" in h], [h["val"] for h in history if "val" in h], marker="s",
                label="val")  # fmt: skip
    ax.set_xlabel("epoch")
    ax.set_ylabel("loss")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def is_best(history: list[dict[str, float]]) -> bool:
    """Whether the last epoch of ``history`` has the lowest validation loss so far (False without validation)."""
    vals = [h["val"] for h in history if "val" in h]
    return bool(vals) and "val" in history[-1] and history[-1]["val"] <= min(vals)


def train(cfg: TrainConfig, resume: bool = False) -> dict[str, Any]:
    """Run (or continue) training; returns the final checkpoint dict."""
    started = time.monotonic()
    torch.manual_seed(cfg.seed)
    device = pick_device(cfg.device)
    cfg.out.mkdir(parents=True, exist_ok=True)
    last = cfg.out / "last.pt"
    ckpt: dict[str, Any] | None = None
    if resume and last.is_file():
        ckpt = torch.load(last, map_location="cpu", weights_only=False)
        if ckpt["kind"] != cfg.model:
            raise SystemExit(f"{last} holds a {ckpt['kind']} model, not {cfg.model}")
        if ckpt["epoch"] >= cfg.epochs:
            logger.info("%s already trained for %d epochs", cfg.model, ckpt["epoch"])
            return ckpt
    future = 6 if cfg.model == "admlp" else 4
    image = tuple(cfg.image_size) if cfg.model == "tcp" else None
    split = has_split(cfg.data)
    train_part = "train" if split else "all"
    data = load_or_extract(cfg.data, cfg.model, train_part, future, cfg.out, image, cfg.workers)  # type: ignore[arg-type]
    val = None
    if split:
        try:
            val = load_or_extract(cfg.data, cfg.model, "val", future, cfg.out, image, cfg.workers)  # type: ignore[arg-type]
        except ValueError as exc:
            logger.warning("no validation: %s", exc)
    if ckpt is not None:
        model_config = ckpt["model_config"]
    elif cfg.model == "admlp":
        model_config = ADMLPConfig(future_steps=future).to_dict()
    else:
        feature_dim = int(data["feature"].shape[1]) if "feature" in data else 0
        model_config = TCPConfig(image_height=image[0], image_width=image[1], future_steps=future,  # type: ignore[index]
                                 feature_dim=feature_dim).to_dict()  # fmt: skip
    model = build_model(cfg.model, model_config).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=max(1, cfg.epochs))
    history: list[dict[str, float]] = []
    start_epoch = 0
    if ckpt is not None:
        model.load_state_dict(ckpt["model"])
        opt.load_state_dict(ckpt["optimizer"])
        sched.load_state_dict(ckpt["scheduler"])
        history, start_epoch = list(ckpt["history"]), int(ckpt["epoch"])
        logger.info("resuming %s at epoch %d of %d", cfg.model, start_epoch + 1, cfg.epochs)
    camera_hw = data.pop(CAMERA_HW, None)
    if val is not None:
        val.pop(CAMERA_HW, None)
    # Tensors go to the device once: a TCP corpus of 40 000 frames at 144x256 is ~4.4 GB.
    data = {k: v.to(device) for k, v in data.items()}
    if val is not None:
        val = {k: v.to(device) for k, v in val.items()}
    loss_fn = admlp_loss if cfg.model == "admlp" else tcp_loss
    gen = torch.Generator().manual_seed(cfg.seed + start_epoch)
    amp = device.type == "cuda"
    epoch_seconds = 0.0
    for epoch in range(start_epoch + 1, cfg.epochs + 1):
        elapsed = time.monotonic() - started
        if cfg.time_budget is not None and elapsed + epoch_seconds > cfg.time_budget:
            logger.warning("time budget %.0f s reached after epoch %d: run again with --resume", cfg.time_budget,
                           epoch - 1)  # fmt: skip
            break
        t0 = time.monotonic()
        model.train()
        total, count = 0.0, 0
        for batch in _batches(data, cfg.batch_size, True, gen):
            with torch.autocast(device.type, dtype=torch.bfloat16, enabled=amp):
                loss = loss_fn(model, batch)  # type: ignore[arg-type]
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            n = len(batch["speed"])
            total += float(loss.detach()) * n
            count += n
        sched.step()
        row = {"epoch": float(epoch), "train": total / max(count, 1), "seconds": time.monotonic() - t0}
        if val is not None:
            model.eval()
            vt, vn = 0.0, 0
            with torch.no_grad(), torch.autocast(device.type, dtype=torch.bfloat16, enabled=amp):
                for batch in _batches(val, cfg.batch_size, False, None):
                    vt += float(loss_fn(model, batch)) * len(batch["speed"])  # type: ignore[arg-type]
                    vn += len(batch["speed"])
            row["val"] = vt / max(vn, 1)
        history.append(row)
        epoch_seconds = time.monotonic() - t0
        ckpt = {
            "kind": cfg.model, "model_config": model_config, "model": model.state_dict(),
            "optimizer": opt.state_dict(), "scheduler": sched.state_dict(), "epoch": epoch, "history": history,
            "frames": int(len(data["speed"])), "data": str(cfg.data),
        }  # fmt: skip
        if camera_hw is not None:
            ckpt["camera_hw"] = [int(v) for v in camera_hw]
        tmp = cfg.out / f".epoch_{epoch:03d}.tmp"
        torch.save(ckpt, tmp)
        tmp.replace(cfg.out / f"epoch_{epoch:03d}.pt")
        torch.save(ckpt, tmp)
        tmp.replace(last)
        if is_best(history):
            # A small corpus over-fits within a few epochs (val loss rising while train falls): the agents drive
            # best.pt, the epoch of lowest val loss, where there is one.
            torch.save(ckpt, tmp)
            tmp.replace(cfg.out / "best.pt")
        logger.info("%s epoch %d/%d: train %.4f%s (%.1f s)", cfg.model, epoch, cfg.epochs, row["train"],
                    f", val {row['val']:.4f}" if "val" in row else "", epoch_seconds)  # fmt: skip
        plot_curve(history, cfg.curve or cfg.out / "loss.png", f"{cfg.model}: loss per epoch")
    if ckpt is None:
        raise SystemExit("no epoch was trained (time budget too small?)")
    return ckpt


def _size(text: str) -> tuple[int, int]:
    w, _, h = text.lower().partition("x")
    return int(h), int(w)


def main(argv: list[str] | None = None) -> int:
    """CLI entry point."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", choices=("admlp", "tcp"), required=True)
    p.add_argument("--data", type=Path, required=True, help="corpus root (b2d-collect --out)")
    p.add_argument("--out", type=Path, required=True, help="run folder: checkpoints, cached tensors, loss.png")
    p.add_argument("--epochs", type=int, default=20)
    p.add_argument("--batch-size", type=int, default=None, help="default 256 (admlp) / 64 (tcp)")
    p.add_argument("--lr", type=float, default=None, help="default 1e-3 (admlp) / 3e-4 (tcp)")
    p.add_argument("--device", default="auto", help="auto, cpu, cuda, cuda:1 ...")
    p.add_argument("--image-size", type=_size, default=(144, 256), metavar="WxH", help="TCP input (default 256x144)")
    p.add_argument("--workers", type=int, default=0, help="DataLoader workers for the one reading pass")
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads")
    p.add_argument("--time-budget", type=float, default=None, help="seconds; stop between epochs, --resume later")
    p.add_argument("--curve", type=Path, default=None, help="loss PNG (default OUT/loss.png)")
    p.add_argument("--resume", action="store_true", help="continue from OUT/last.pt")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s", stream=sys.stderr)
    if args.threads:
        torch.set_num_threads(args.threads)
    cfg = TrainConfig(
        model=args.model, data=args.data, out=args.out, epochs=args.epochs,
        batch_size=args.batch_size or (256 if args.model == "admlp" else 64),
        lr=args.lr or (1e-3 if args.model == "admlp" else 3e-4), device=args.device, image_size=args.image_size,
        workers=args.workers, seed=args.seed, time_budget=args.time_budget, curve=args.curve,
    )  # fmt: skip
    ckpt = train(cfg, resume=args.resume)
    final = ckpt["history"][-1] if ckpt["history"] else {}
    print(f"{cfg.model}: epoch {ckpt['epoch']}/{cfg.epochs}, train loss {final.get('train', math.nan):.4f}, "
          f"{ckpt['frames']} frames, checkpoint {cfg.out / 'last.pt'}")  # fmt: skip
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    raise SystemExit(main())
