"""A trained network with everything needed to apply it to new p(v,t) (what a checkpoint holds)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch
from torch import nn

from processing.classifier.preprocess import PreprocessConfig, preprocess_links


@dataclass
class Classifier:
    """A trained network with everything needed to apply it to new p(v,t)."""

    model: nn.Module
    preprocess: PreprocessConfig
    classes: list[str]
    links: list[str]
    meta: dict = field(default_factory=dict)

    def inputs(self, samples: list[dict]) -> np.ndarray:
        """X [N, n_links, V, T] from samples {link: {"p_vt", "velocity", "time"}}."""
        return np.stack([preprocess_links(s, self.links, self.preprocess) for s in samples])

    def predict_proba(self, x: np.ndarray, batch_size: int = 256) -> np.ndarray:
        """Class probabilities [N, n_classes] of preprocessed inputs X [N, n_links, V, T]."""
        self.model.eval()
        out = []
        with torch.no_grad():
            for s in range(0, len(x), batch_size):
                out.append(torch.softmax(self.model(torch.as_tensor(x[s:s + batch_size])), dim=1).numpy())
        return np.concatenate(out) if out else np.zeros((0, len(self.classes)), np.float32)

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Predicted label indices [N] of preprocessed inputs X [N, n_links, V, T]."""
        return self.predict_proba(x).argmax(axis=1)


__all__ = ["Classifier"]
