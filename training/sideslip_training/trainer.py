"""One training of one network: Adam on the MSE of normalised β, early stopping on
validation MAE, the best epoch's weights kept.

With ``average_weights`` the network that is scored and kept is an exponential moving
average of the weights over about the last epoch's steps (``torch.optim.swa_utils``),
not the last step's weights: Adam at a constant learning rate ends each epoch at a
random point of the noise around a minimum, which on a small recording moved the test
RMSE by up to ±40 % between seeds (docs/training.md, "Weight averaging").

Reads top to bottom: config → data on the device → epoch loop → result. Everything is
seeded (weights, shuffling); on CPU two runs with the same seed give the same weights
bit for bit (tested), on CUDA the LSTM kernels are not deterministic.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field

import numpy as np
import torch
from torch import nn
from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

from .member_net import MemberNet, split_members
from .model import ModelConfig, SideslipNet
from .normalize import Normalizer
from .windows import WindowIndex

VAL_BATCH = 2048  # windows per validation forward pass: bounds GPU memory, not accuracy


@dataclass(frozen=True)
class TrainConfig:
    """What one training needs besides the data. Units: learning rate per Adam step."""

    architecture: str = "lstm"  # lstm | bilstm
    hidden_units: int = 64
    layers: int = 1
    learning_rate: float = 1e-3
    max_epochs: int = 100
    patience: int = 10
    batch_size: int = 512
    seed: int = 0
    device: str = "auto"  # auto | cpu | cuda
    average_weights: bool = False
    keep_members: bool = True
    """Fine-tuning a merged model: train each member alone, the weights between members
    staying zero (:mod:`sideslip_training.member_net`); False trains the wide network."""

    def __post_init__(self) -> None:
        if self.architecture not in ("lstm", "bilstm"):
            raise ValueError(f"architecture must be lstm or bilstm, got {self.architecture!r}")
        if self.hidden_units < 1 or self.layers < 1:
            raise ValueError("hidden_units and layers must be >= 1")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise ValueError(f"learning_rate must be > 0, got {self.learning_rate!r}")
        if self.max_epochs < 1 or self.patience < 1 or self.batch_size < 1:
            raise ValueError("max_epochs, patience and batch_size must be >= 1")


@dataclass(frozen=True)
class EpochRecord:
    epoch: int
    train_loss: float  # mean MSE of normalised β over the epoch's batches
    val_mae_deg: float
    seconds: float
    windows_per_s: float


@dataclass
class TrainResult:
    model: SideslipNet  # the best epoch's weights, on the CPU, in eval mode
    best_epoch: int
    """1-based; 0 when fine-tuning and no epoch beat the starting weights on validation
    (the model is then those weights)."""
    best_val_mae_deg: float
    history: list[EpochRecord] = field(default_factory=list)
    seconds: float = 0.0
    device: str = "cpu"
    stopped_early: bool = False
    start_val_mae_deg: float | None = None
    """Validation MAE of the starting weights when fine-tuning (None from scratch): the
    bar an epoch must beat, the lower of ``start_val_mae_forms``."""
    start_val_mae_forms: dict[str, float] = field(default_factory=dict)
    """The start's validation MAE per way the node may run it: ``alone``, and
    ``averaged`` (with its mirror image) when that is the start's default."""

    def summary(self) -> dict[str, object]:
        return {
            "best_epoch": self.best_epoch,
            "best_val_mae_deg": self.best_val_mae_deg,
            "start_val_mae_deg": self.start_val_mae_deg,
            "start_val_mae_forms": self.start_val_mae_forms,
            "epochs_run": len(self.history),
            "stopped_early": self.stopped_early,
            "seconds": self.seconds,
            "device": self.device,
            "mean_windows_per_s": (
                sum(r.windows_per_s for r in self.history) / len(self.history)
                if self.history
                else 0.0
            ),
            "history": [asdict(r) for r in self.history],
        }


def pick_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("device cuda requested but torch sees no CUDA device")
    return torch.device(name)


@dataclass(frozen=True)
class MirrorTerms:
    """The left-right mirror of a normalised window, ``x * scale + shift``, and the
    network's output averaged with its mirror image's, ``(y - y_mirror) / 2 - offset``:
    what the node's ``pso_lstm.mirror_average`` publishes, in normalised units
    (:func:`sideslip_training.evaluate.predict_run` does the same on raw inputs)."""

    scale: torch.Tensor  # (F,) −1 for an input the mirror negates, +1 otherwise
    shift: torch.Tensor  # (F,) (scale·mean − mean) / std of each input
    offset: float  # beta_mean / beta_std: the mirror negates β, not its normalisation

    @classmethod
    def of(cls, normalizer: Normalizer, device: torch.device) -> MirrorTerms:
        from sideslip_msgs_py.mirror import input_signs

        signs = input_signs(normalizer.features)
        mean, std = np.asarray(normalizer.mean), np.asarray(normalizer.std)
        return cls(
            scale=torch.as_tensor(signs, dtype=torch.float32, device=device),
            shift=torch.as_tensor((signs * mean - mean) / std, dtype=torch.float32, device=device),
            offset=float(normalizer.beta_mean / normalizer.beta_std),
        )

    def average(self, model: nn.Module, x: torch.Tensor) -> torch.Tensor:
        return 0.5 * (model(x) - model(x * self.scale + self.shift)) - self.offset


def mae_deg(
    model: nn.Module,
    data,
    normalizer: Normalizer,
    device: torch.device,
    n: int,
    mirror: MirrorTerms | None = None,
) -> float:
    """Validation MAE of β in degrees over all ``n`` windows of ``data``; of the
    network averaged with its mirror image when ``mirror`` is given."""
    model.eval()
    total = 0.0
    with torch.inference_mode():
        for start in range(0, n, VAL_BATCH):
            idx = torch.arange(start, min(start + VAL_BATCH, n), device=device)
            x, y = data.batch(idx)
            out = model(x) if mirror is None else mirror.average(model, x)
            total += float((out - y).abs().sum())
    return math.degrees(total / max(n, 1) * normalizer.beta_std)


def train_model(
    cfg: TrainConfig,
    train: WindowIndex,
    val: WindowIndex,
    normalizer: Normalizer,
    *,
    on_epoch: Callable[[EpochRecord], None] | None = None,
    init_state: Mapping[str, torch.Tensor] | None = None,
    keep_last: bool = False,
    deployed_mirror: tuple[bool, bool] = (False, False),
) -> TrainResult:
    """Train a :class:`SideslipNet` on ``train``, stop early on ``val`` MAE; from the
    weights ``init_state`` (fine-tuning) when given, else from a seeded initialisation;
    a merged ``init_state`` trains member by member unless ``cfg.keep_members`` is False.
    A fine-tuning is scored on ``val`` before its first step too, and keeps the
    starting weights (``best_epoch`` 0) when no epoch beats them: it never returns a
    model worse on validation than the one it started from.
    ``keep_last``: run all ``max_epochs`` and keep the last epoch's weights (a refit
    whose epoch count was chosen before, when ``val`` is part of ``train``).
    ``deployed_mirror``: whether the node's default averages (the start, the trained
    network) with its mirror image (``pso_lstm.mirror_average``). Every epoch is scored
    on ``val`` as it will run; the start alone, and averaged too when that is its
    default, and an epoch is kept only when it beats the start both ways: the start is
    the validated model, and a validation stretch driven mostly one way round favours a
    network alone over an average (docs/evaluation/fit-bags, "The handover")."""
    device = pick_device(cfg.device)
    torch.manual_seed(cfg.seed)
    model = SideslipNet(
        ModelConfig(cfg.architecture, len(normalizer.features), cfg.hidden_units, cfg.layers)
    )
    net: nn.Module = model
    if init_state is not None:
        model.load_state_dict(dict(init_state), strict=True)
        if cfg.keep_members:
            net = split_members(model) or model
    net = net.to(device)
    trained = [p for p in net.parameters() if p.requires_grad]
    optimiser = torch.optim.Adam(trained, lr=cfg.learning_rate)
    loss_fn = nn.MSELoss()
    train_t, val_t = train.to_torch(device), val.to_torch(device)
    n_train, n_val = len(train.ends), len(val.ends)
    if n_train == 0 or n_val == 0:
        raise ValueError(f"no windows to train on ({n_train}) or validate on ({n_val})")
    shuffle = torch.Generator(device="cpu").manual_seed(cfg.seed)
    averaged = None
    if cfg.average_weights:
        # A moving average whose memory is about one epoch's steps, whatever the data size.
        decay = 1.0 - 1.0 / max(2, math.ceil(n_train / cfg.batch_size))
        averaged = AveragedModel(net, multi_avg_fn=get_ema_multi_avg_fn(decay))
    scored = net if averaged is None else averaged.module

    result = TrainResult(model=model, best_epoch=0, best_val_mae_deg=math.inf, device=str(device))
    best_state = copy.deepcopy(net.state_dict())
    mirror = MirrorTerms.of(normalizer, device) if any(deployed_mirror) else None
    epoch_mirror = mirror if deployed_mirror[1] else None
    if init_state is not None and not keep_last:
        forms = {"alone": None, **({"averaged": mirror} if deployed_mirror[0] else {})}
        result.start_val_mae_forms = {
            form: mae_deg(scored, val_t, normalizer, device, n_val, terms)
            for form, terms in forms.items()
        }
        result.start_val_mae_deg = min(result.start_val_mae_forms.values())
        if math.isfinite(result.start_val_mae_deg):
            result.best_val_mae_deg = result.start_val_mae_deg
    since_best = 0
    started = time.perf_counter()
    for epoch in range(1, cfg.max_epochs + 1):
        t0 = time.perf_counter()
        net.train()
        order = torch.randperm(n_train, generator=shuffle).to(device)
        loss_sum, batches = 0.0, 0
        for start in range(0, n_train, cfg.batch_size):
            x, y = train_t.batch(order[start : start + cfg.batch_size])
            optimiser.zero_grad(set_to_none=True)
            loss = loss_fn(net(x), y)
            loss.backward()
            optimiser.step()
            if averaged is not None:
                averaged.update_parameters(net)
            loss_sum += float(loss.detach())
            batches += 1
        train_seconds = time.perf_counter() - t0
        val_mae = mae_deg(scored, val_t, normalizer, device, n_val, epoch_mirror)
        record = EpochRecord(
            epoch,
            loss_sum / batches,
            val_mae,
            time.perf_counter() - t0,
            n_train / train_seconds,
        )
        result.history.append(record)
        if on_epoch is not None:
            on_epoch(record)
        if not math.isfinite(record.train_loss):
            break  # diverged: the best earlier epoch (if any) stands
        if keep_last or val_mae < result.best_val_mae_deg:
            result.best_val_mae_deg, result.best_epoch = val_mae, epoch
            best_state = copy.deepcopy(scored.state_dict())
            since_best = 0
        else:
            since_best += 1
            if since_best >= cfg.patience:
                result.stopped_early = True
                break
    if not math.isfinite(result.best_val_mae_deg):
        raise ValueError(
            f"no epoch with a finite validation MAE (lr {cfg.learning_rate:g}, "
            f"{cfg.hidden_units} units): training diverged"
        )
    net.load_state_dict(best_state)
    result.model = (net.joined() if isinstance(net, MemberNet) else net).cpu().eval()
    result.seconds = time.perf_counter() - started
    return result
