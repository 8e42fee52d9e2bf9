"""The spreading kernel of the gridded synthesiser (`processing.synthesis.grid`): design and error bound.

phi(t) = exp(beta (sqrt(1 - (2t/w)^2) - 1)) - exp(-beta) for |t| < w/2 cells, 0 outside: the "exponential of
semicircle" of Barnett, Magland & af Klinteberg (SIAM J. Sci. Comput. 41, 2019), beta = 0.97 pi w
(1 - 1/(2 oversample)) as there, minus its edge value so that it is continuous. A path at grid position
X = f + z (reference cell f, offset z in [-drift, 1 + drift]) weighs cell f - w/2 + q (q = 0 .. w + 1) by
phi(z + w/2 - q); the synthesiser uses instead the degree-DEGREE polynomials in y = (2z - 1)/(1 + 2 drift)
fitted here (Chebyshev least squares), so that a path only contributes the moments c y^d of its reference cell.

Error per path and sample (`SpreadKernel.error_bound`): sample n' (centred, |n'| <= N/2) of the grid's inverse
DFT over phihat(n'/M) is c exp(j 2 pi n' X / M) (1 + e) with e = sum_q w_q(z) exp(-j 2 pi xi (X - l_q)) / phihat(xi)
- 1, xi = n'/M: the kernel's aliases and the polynomial fit together, a function of z and xi only. Its largest
modulus over z and |xi| <= 1/(2 oversample) is the bound (measured on 801 x 129 points; smooth in both).
At the defaults (oversample 4, w = 8, drift 0.25, degree 5) it is 1.8e-6 (-115 dB); the degree limits it
(degree 6: 8e-8, at one more moment per path and chirp); oversample 2 would need degree 7 for 1.0e-6.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import chebyshev

from processing.errors import InputError

OVERSAMPLE = 4  # grid cells per range bin (M / N)
WIDTH = 8  # kernel support [cells]
DRIFT = 0.25  # largest drift [cells] of a path from its reference cell before the cell is re-chosen
DEGREE = 5  # polynomial degree of the fitted weights; fixed: the moment loop of `synthesis_grid._spread` is
# unrolled for it


@dataclass(frozen=True)
class SpreadKernel:
    """A designed spreading kernel (see the module docstring).

    Attributes:
        oversample: grid cells per range bin (M = oversample x N).
        width: support w of phi [cells].
        drift: offset margin [cells]: a path's offset from its reference cell stays in [-drift, 1 + drift].
        beta: shape parameter of phi.
        weights: [w + 2, DEGREE + 1] monomial coefficients (lowest first) in y of the weight on cell
            f - w/2 + q, y = (2 z - 1) / (1 + 2 drift), z = X - f.
    """

    oversample: int
    width: int
    drift: float
    beta: float
    weights: np.ndarray

    @functools.cached_property
    def error_bound(self) -> float:
        """Largest relative error per path and sample, over offsets z in [-drift, 1 + drift] (801 points) and
        |n'/M| <= 1/(2 oversample) (129 points): |sum_q w_q(z) exp(-j 2 pi xi (X - l_q)) / phihat(xi) - 1|."""
        return _error_bound(self)

    @property
    def n_cells(self) -> int:
        """Cells a path's moments are spread onto (w + 2)."""
        return self.width + 2

    def phi(self, t: np.ndarray) -> np.ndarray:
        """The kernel phi(t) (t in cells)."""
        x = 2.0 * np.asarray(t, dtype=np.float64) / self.width
        inside = np.abs(x) < 1
        return np.where(inside, np.exp(self.beta * (np.sqrt(np.where(inside, 1 - x * x, 0.0)) - 1))
                        - math.exp(-self.beta), 0.0)

    def phihat(self, xi: np.ndarray) -> np.ndarray:
        """Fourier transform of phi at xi [cycles per cell]: 2 int_0^{w/2} phi(t) cos(2 pi xi t) dt, with
        t = (w/2) sin(theta), which makes the integrand analytic (64-point Gauss-Legendre is exact to 1e-16)."""
        nodes, wts = np.polynomial.legendre.leggauss(64)
        theta = (nodes + 1) * math.pi / 4
        t = 0.5 * self.width * np.sin(theta)
        f = (np.exp(self.beta * (np.cos(theta) - 1)) - math.exp(-self.beta)) * 0.5 * self.width * np.cos(theta)
        xi = np.asarray(xi, dtype=np.float64)
        return 2 * (np.cos(2 * np.pi * xi[..., None] * t) @ (f * wts)) * math.pi / 4

    def fitted_weights(self, z: np.ndarray) -> np.ndarray:
        """Weights [w + 2, Z] the synthesiser uses for offsets z [Z] (cells) from the reference cell."""
        y = (2 * np.asarray(z, dtype=np.float64) - 1) / (1 + 2 * self.drift)
        return np.stack([np.polynomial.polynomial.polyval(y, c) for c in self.weights])


def _error_bound(k: SpreadKernel) -> float:
    z = np.linspace(-k.drift, 1 + k.drift, 801)
    xi = np.linspace(-0.5 / k.oversample, 0.5 / k.oversample, 129)
    q = np.arange(k.n_cells)
    t = z[None, :] + k.width / 2 - q[:, None]  # X - l for cell l = f - w/2 + q
    s = np.einsum("qz,qzx->zx", k.fitted_weights(z), np.exp(-2j * np.pi * t[:, :, None] * xi))
    return float(np.abs(s / k.phihat(xi) - 1).max())


@functools.lru_cache(maxsize=8)
def spread_kernel(oversample: int = OVERSAMPLE, width: int = WIDTH, drift: float = DRIFT) -> SpreadKernel:
    """Design the kernel (beta, fitted weights); cached. Its `error_bound` is computed on first use."""
    if oversample < 2 or width < 2 or width % 2 or not 0 <= drift <= 0.5:
        raise InputError(f"need oversample >= 2, an even width >= 2 and 0 <= drift <= 0.5, got {oversample}, "
                         f"{width}, {drift}")
    beta = 0.97 * math.pi * width * (1 - 0.5 / oversample)
    k = SpreadKernel(oversample, width, drift, beta, np.zeros((width + 2, DEGREE + 1)))
    y = np.cos(np.pi * (np.arange(4 * DEGREE) + 0.5) / (4 * DEGREE))  # Chebyshev nodes in y
    z = ((1 + 2 * drift) * y + 1) / 2
    fits = [chebyshev.cheb2poly(chebyshev.chebfit(y, k.phi(z + width / 2 - q), DEGREE))
            for q in range(width + 2)]
    return SpreadKernel(oversample, width, drift, beta, np.array(fits))


