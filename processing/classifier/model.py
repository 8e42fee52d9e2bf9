"""The seed's multiperspective DCNN (Sect. VII-A, Fig. 9): one feature-extraction network (FEN) per radar,
fused features, an MLP head.

FEN: four blocks of [conv (64, 72, 80, 96 kernels of k x k, k = 3 or 4) -> (BatchNorm) -> ReLU ->
2x2 max pool -> 10 % dropout], then flatten. BatchNorm is not in the seed's description; it is on by
default because without it the network sat at chance for many epochs on small datasets (measured), and
`batch_norm=False` gives the literal seed stack. The seed's flatten size, 18816 = 96 x 14 x 14, matches 3x3 'valid'
convolutions on a 256 x 256 image; the default here is the same 3x3 'valid' stack on a 64 x 64 image
(the native 64 velocity bins of a 64-chirp window), which gives 96 x 2 x 2 = 384 features per radar
and keeps training of the seed-size dataset within minutes on two CPU cores. MLP: Linear -> ReLU -> 15 % dropout -> Linear to the class logits.

Options (one code path): `n_branches` 1 (single radar) or 2+; `fusion` concat (seed), sum, max, mean;
`shared_weights` (one FEN applied to every radar); `kernel_size` 3 or 4; `padding` same or valid.
"""
from __future__ import annotations

from typing import Literal

import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn


class ModelConfig(BaseModel):
    """Architecture of the multiperspective DCNN; saved inside checkpoints."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    n_classes: int = Field(5, ge=2)
    n_branches: int = Field(2, ge=1, le=8, description="radars (one FEN each)")
    input_size: tuple[int, int] = Field((64, 64), description="(n_velocity, n_time) of each input image")
    channels: tuple[int, ...] = Field((64, 72, 80, 96), description="kernels per conv layer (seed)")
    kernel_size: int = Field(3, ge=2, le=7, description="k of the k x k kernels (seed: 3 or 4)")
    padding: Literal["same", "valid"] = "valid"
    fen_dropout: float = Field(0.10, ge=0, lt=1)
    mlp_dropout: float = Field(0.15, ge=0, lt=1)
    mlp_hidden: int = Field(128, ge=4)
    fusion: Literal["concat", "sum", "max", "mean"] = "concat"
    shared_weights: bool = False
    batch_norm: bool = Field(True, description="BatchNorm after each conv (not in the seed's text; "
                             "makes training converge in a few epochs instead of tens)")


class FEN(nn.Module):
    """Feature-extraction network of one radar: [B, 1, V, T] -> [B, features]."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        layers, c_in = [], 1
        for c in cfg.channels:
            layers += [nn.Conv2d(c_in, c, cfg.kernel_size, padding=cfg.padding)]
            layers += [nn.BatchNorm2d(c)] if cfg.batch_norm else []
            layers += [nn.ReLU(inplace=True), nn.MaxPool2d(2), nn.Dropout(cfg.fen_dropout)]
            c_in = c
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
            raise ValueError(f"input {cfg.input_size} is too small for {len(cfg.channels)} '{cfg.padding}' "
                             f"{cfg.kernel_size}x{cfg.kernel_size} conv/pool layers (use padding 'same' or a larger input)")
        self.n_features = n_feat * (cfg.n_branches if cfg.fusion == "concat" else 1)
        self.mlp = nn.Sequential(nn.Linear(self.n_features, cfg.mlp_hidden), nn.ReLU(inplace=True),
                                 nn.Dropout(cfg.mlp_dropout), nn.Linear(cfg.mlp_hidden, cfg.n_classes))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.ndim != 4 or x.shape[1] != self.cfg.n_branches:
            raise ValueError(f"expected input [B, {self.cfg.n_branches}, V, T], got {tuple(x.shape)}")
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
