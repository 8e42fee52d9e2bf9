"""Figures of classifier training: loss and accuracy curves per epoch (the seed's Fig. 10)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def save_figure(fig, path: str | Path, dpi: int = 120) -> Path:
    """Lay out, write atomically (creating the folder) and close a matplotlib figure; returns the path."""
    import matplotlib.pyplot as plt

    from processing.atomic import savefig_atomic

    fig.tight_layout()
    try:
        return savefig_atomic(fig, path, dpi=dpi)
    finally:
        plt.close(fig)


def plot_history(history: dict, path: str | Path, best_epoch: int | None = None, title: str | None = None) -> Path:
    """PNG with training/validation loss (left) and accuracy in % (right) against epoch."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    epochs = np.arange(1, len(history.get("train_loss", [])) + 1)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8))
    a1.plot(epochs, history["train_loss"], "o-", ms=3, label="training")
    a1.plot(epochs, history["val_loss"], "s-", ms=3, label="validation")
    a1.set_ylabel("cross-entropy loss")
    a2.plot(epochs, 100 * np.asarray(history["train_acc"]), "o-", ms=3, label="training")
    a2.plot(epochs, 100 * np.asarray(history["val_acc"]), "s-", ms=3, label="validation")
    a2.set_ylabel("accuracy [%]")
    for a in (a1, a2):
        a.set_xlabel("epoch")
        a.grid(alpha=0.3)
        if best_epoch:
            a.axvline(best_epoch, color="grey", ls="--", lw=1, label=f"best epoch {best_epoch}")
        a.legend()
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, path)
