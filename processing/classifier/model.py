"""The seed's multiperspective DCNN (Sect. VII-A, Fig. 9): one feature-extraction network (FEN) per radar,
fused features, an MLP head.

FEN: four blocks of [conv (64, 72, 80, 96 kernels of k x k, k = 3 or 4) -> (BatchNorm) -> ReLU ->
2x2 max pool -> 10 % dropout], then flatten (the pool runs before the ReLU, which gives the same numbers).
BatchNorm is not in the seed's description; it is on by default because without it the network sat at chance
for many epochs on small datasets (measured), and
`batch_norm=False` gives the literal seed stack. The seed's flatten size, 18816 = 96 x 14 x 14, matches 3x3 'valid'
convolutions on a 256 x 256 image; the default here is the same 3x3 'valid' stack on a 64 x 64 image
(the native 64 velocity bins of a 64-chirp window), which gives 96 x 2 x 2 = 384 features per radar
and keeps training of the seed-size dataset within minutes on two CPU cores. MLP: Linear -> ReLU -> 15 % dropout ->
Linear to the class logits.

Options (one code path): `n_branches` 1 (single radar) or 2+; `fusion` concat (seed), sum, max, mean;
`shared_weights` (one FEN applied to every radar); `kernel_size` 3 or 4; `padding` same or valid;
`time_pool` ('none', seed; 'max' or 'mean'): the FEN's last feature map pooled over its time axis before
flattening, so the features say *what* happened at any time rather than *when* in the clip (issue 27: a
simulation-trained model had learnt where each activity sits in its clip). Checkpoints written before the
field existed load with 'none', what they were trained with.
"""
from __future__ import annotations

from typing import Annotated, Literal

import torch
from pydantic import BaseModel, ConfigDict, Field, model_validator
from torch import nn

from processing.errors import InputError

# Size limits, checked from the configuration before anything is allocated (a checkpoint may ask for anything):
MAX_PARAMETERS = 50_000_000  # 200 MB of float32 weights, ~0.8 GB with Adam's state and gradients
MAX_ACTIVATION_BYTES = 256 * 2**20  # forward activations of one sample (the seed's 256 x 256 input needs ~0.1 GB)


class ModelConfig(BaseModel):
    """Architecture of the multiperspective DCNN; saved inside checkpoints."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    n_classes: int = Field(5, ge=2, le=1000)
    n_branches: int = Field(2, ge=1, le=8, description="radars (one FEN each)")
    input_size: tuple[Annotated[int, Field(ge=8, le=4096)], Annotated[int, Field(ge=8, le=4096)]] = Field(
        (64, 64), description="(n_velocity, n_time) of each input image (as PreprocessConfig's bounds)")
    channels: tuple[Annotated[int, Field(ge=1, le=1024)], ...] = Field(
        (64, 72, 80, 96), min_length=1, max_length=8, description="kernels per conv layer (seed)")
    kernel_size: int = Field(3, ge=2, le=7, description="k of the k x k kernels (seed: 3 or 4)")
    padding: Literal["same", "valid"] = "valid"
    fen_dropout: float = Field(0.10, ge=0, lt=1)
    mlp_dropout: float = Field(0.15, ge=0, lt=1)
    mlp_hidden: int = Field(128, ge=4, le=65536)
    fusion: Literal["concat", "sum", "max", "mean"] = "concat"
    shared_weights: bool = False
    batch_norm: bool = Field(True, description="BatchNorm after each conv (not in the seed's text; "
                             "makes training converge in a few epochs instead of tens)")
    # measured (simulation only, 180 items, 4 seeds, time_mode 'active'): no gain over 'none' alone or with
    # augmentation; the active crop already removes the activity's position. Kept off by default.
    time_pool: Literal["none", "max", "mean"] = Field("none", description="pool the FEN's last feature map over "
                                                      "time before flattening ('none': the seed's flatten)")

    @model_validator(mode="after")
    def _sizes(self) -> "ModelConfig":
        """Feature-map sizes, parameter count and activation memory from the numbers alone (no allocation)."""
        h, w = self.input_size
        c_in, params, act = 1, 0, 0
        for c in self.channels:
            if self.padding == "valid":
                h, w = h - self.kernel_size + 1, w - self.kernel_size + 1
            if min(h, w) < 2:
                raise InputError(f"input {self.input_size} is too small for {len(self.channels)} '{self.padding}' "
                                 f"{self.kernel_size}x{self.kernel_size} conv/pool layers (use padding 'same' or a "
                                 "larger input)")
            params += c_in * c * self.kernel_size ** 2 + c + (2 * c if self.batch_norm else 0)
            act += 3 * c * h * w * 4  # conv (+ BatchNorm) output and the pooled map, float32
            h, w, c_in = h // 2, w // 2, c
        params *= 1 if self.shared_weights else self.n_branches
        feats = c_in * h * (w if self.time_pool == "none" else 1) * (self.n_branches if self.fusion == "concat" else 1)
        params += feats * self.mlp_hidden + self.mlp_hidden + self.mlp_hidden * self.n_classes + self.n_classes
        if act * self.n_branches > MAX_ACTIVATION_BYTES:
            raise InputError(f"one input sample would need {act * self.n_branches / 2**20:.0f} MiB of activations, "
                             f"more than {MAX_ACTIVATION_BYTES >> 20} MiB (smaller input_size or channels)")
        if params > MAX_PARAMETERS:
            raise InputError(f"the network would have {params:.3g} parameters, more than the limit of "
                             f"{MAX_PARAMETERS:.3g} (smaller input_size, channels or mlp_hidden)")
        return self

    def n_parameters(self) -> int:
        """Trainable parameters of the network this configuration builds (BatchNorm weights included)."""
        return sum(p.numel() for p in build_model(self).parameters())


class TimePool(nn.Module):
    """[B, C, V, T] -> [B, C, V]: max or mean over the time axis (the last)."""

    def __init__(self, mode: str):
        super().__init__()
        self.mode = mode

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x.amax(dim=-1) if self.mode == "max" else x.mean(dim=-1)

    def extra_repr(self) -> str:
        return self.mode


class Dropout(nn.Dropout):
    """`nn.Dropout` whose mask is drawn in the tensor's logical (N, C, H, W) order whatever its memory layout.

    torch fills a channels-last tensor's mask in memory order, so the same seed would drop other elements
    than for the contiguous layout; drawing on a contiguous copy keeps one random stream for both layouts
    (training in channels-last then differs from contiguous by float rounding only).
    """

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.training or self.p == 0 or x.is_contiguous():
            return super().forward(x)
        # what F.dropout does on CPU (Bernoulli noise divided by the keep probability, times x), with the noise
        # drawn contiguous and only then laid out like x
        keep = 1.0 - self.p
        noise = torch.empty(x.shape, dtype=x.dtype).bernoulli_(keep)
        return x * noise.contiguous(memory_format=torch.channels_last).div_(keep)


class FEN(nn.Module):
    """Feature-extraction network of one radar: [B, 1, V, T] -> [B, features]."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        layers: list[nn.Module] = []
        c_in = 1
        for c in cfg.channels:
            layers += [nn.Conv2d(c_in, c, cfg.kernel_size, padding=cfg.padding)]
            layers += [nn.BatchNorm2d(c)] if cfg.batch_norm else []
            # the seed's conv -> ReLU -> pool, with the pool first: max and ReLU commute exactly (ReLU is
            # monotone; same outputs and gradients, bit for bit), and the ReLU then runs on a quarter of the
            # values. Parameter-free, so the state-dict keys are unchanged.
            layers += [nn.MaxPool2d(2), nn.ReLU(inplace=True), Dropout(cfg.fen_dropout)]
            c_in = c
        if cfg.time_pool != "none":  # parameter-free, so the state-dict keys are those of 'none'
            layers += [TimePool(cfg.time_pool)]
        self.net = nn.Sequential(*layers, nn.Flatten())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


class MultiPerspectiveDCNN(nn.Module):
    """Input [B, n_branches, V, T] (one image per radar) -> class logits [B, n_classes]."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.cfg = cfg
        n_fen = 1 if cfg.shared_weights else cfg.n_branches
        self.fens = nn.ModuleList(FEN(cfg) for _ in range(n_fen))
        try:
            with torch.no_grad():
                n_feat = self.fens[0](torch.zeros(1, 1, *cfg.input_size)).shape[1]
        except RuntimeError:
            n_feat = 0
        if n_feat == 0:
            raise InputError(f"input {cfg.input_size} is too small for {len(cfg.channels)} '{cfg.padding}' "
                             f"{cfg.kernel_size}x{cfg.kernel_size} conv/pool layers (use padding 'same' or a larger "
                             "input)")
        self.n_features = n_feat * (cfg.n_branches if cfg.fusion == "concat" else 1)
        self.mlp = nn.Sequential(nn.Linear(self.n_features, cfg.mlp_hidden), nn.ReLU(inplace=True),
                                 nn.Dropout(cfg.mlp_dropout), nn.Linear(cfg.mlp_hidden, cfg.n_classes))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.ndim != 4 or x.shape[1] != self.cfg.n_branches:
            raise InputError(f"expected input [B, {self.cfg.n_branches}, V, T], got {tuple(x.shape)}")
        feats = [self.fens[0 if self.cfg.shared_weights else i](x[:, i:i + 1]) for i in range(x.shape[1])]
        if self.cfg.fusion == "concat":
            f = torch.cat(feats, dim=1)
        else:
            s = torch.stack(feats, dim=0)
            f = {"sum": s.sum(0), "mean": s.mean(0), "max": s.amax(0)}[self.cfg.fusion]
        return self.mlp(f)


def build_model(cfg: ModelConfig) -> MultiPerspectiveDCNN:
    """A freshly initialised network (initialisation follows torch.manual_seed)."""
    return MultiPerspectiveDCNN(cfg)
