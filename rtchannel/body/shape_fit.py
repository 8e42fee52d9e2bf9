"""From anthropometric values (sex, age, stature, BMI, muscle, proportions) to MakeHuman's macro sliders.

Age: MakeHuman's adult anchors are a 25-year-old ("young", slider 0.5) and a 90-year-old ("old", slider 1),
linear in between (MakeHuman 1.1 ``setAgeYears``). Younger adults use the young anchor: growth in stature
has ended by 18 (WHO 2007 growth reference), and MakeHuman's 18-year-old would be 47 % its 10-year-old
child, with a child's head-to-body ratio. Older than 90 uses the old anchor.

Stature: MakeHuman's height slider is set so that the body (at average weight) is as tall as the requested
stature, which keeps MakeHuman's allometry (its tall bodies have relatively longer legs: the man's hip joint
at 0.50 of the stature at 1.36 m, 0.53 at 1.73 m, 0.56 at 2.45 m); the body is then scaled uniformly to the
exact stature.

Mass: body mass = mesh volume x whole-body density, and BMI = mass / stature^2. Density follows from body
fat (two-compartment model, Siri 1961: fat 0.9007 g/cm^3, fat-free mass 1.100 g/cm^3), and body fat from
BMI, age and sex (Deurenberg, Weststrate & Seidell 1991, Br J Nutr 65:105, SEE ~4 % fat):
BF% = 1.20 BMI + 0.23 age - 10.8 sex - 5.4 (sex 1 male, 0 female), clipped to 5..60 %. This gives
0.97-1.08 g/cm^3 over BMI 17-40 and ages 18-98 (a lean 18-year-old man 1.08, an obese 70-year-old woman
0.97), the range of hydrostatic weighing. Tissue density leaves out the air in the lungs (~3 L at rest): a
real body of the BMI encloses ~4 % more volume than the shaped one, a bias left in (within the Du Bois
check's tolerance).

Weight and muscle: MakeHuman's weight slider changes the volume strongly only on its min-muscle anchors (at
average muscle, min to max weight is BMI ~17 to ~24; at min muscle ~14 to ~40). So the requested muscle is
kept where its anchors reach the requested BMI with weight in [0, `WEIGHT_MAX`], else the muscle nearest to
it that does (heavy bodies are built on the low-muscle anchors, lean ones on the higher). Both the requested
and the used values are recorded (`rtchannel.body.shape.BodyShape.key`).
"""
from __future__ import annotations

from functools import lru_cache

import numba
import numpy as np
from scipy.optimize import brentq

from processing.errors import InputError
from rtchannel.body.avatar import load_avatar
from rtchannel.body.body_targets import N_SKIN, WEIGHT_MAX, MacroValues, anchor_weights, shaped_points_many

YOUNG_YEARS, OLD_YEARS = 25.0, 90.0  # MakeHuman's adult age anchors (slider 0.5 and 1)
FAT_DENSITY_KG_M3 = 900.7  # Siri 1961
LEAN_DENSITY_KG_M3 = 1100.0  # Siri 1961, fat-free mass
BODY_FAT_RANGE = (0.05, 0.60)  # Deurenberg's regression is not extrapolated past these fractions
_MUSCLE_GRID = 11  # muscle values searched when the requested one cannot reach the BMI
_BISECTIONS = 7  # then the boundary toward the requested muscle to 1/(10 * 2^7) of the slider


def age_value(age_years: float) -> float:
    """MakeHuman's age slider value (0.5..1) of an adult of `age_years` (see the module doc)."""
    t = (float(age_years) - YOUNG_YEARS) / (OLD_YEARS - YOUNG_YEARS)
    return 0.5 + 0.5 * min(1.0, max(0.0, t))


def body_fat_fraction(bmi: float, age_years: float, sex: float) -> float:
    """Body fat fraction (0..1) from BMI [kg/m^2], age [years] and sex (0 female, 1 male): Deurenberg 1991."""
    bf = (1.20 * bmi + 0.23 * age_years - 10.8 * sex - 5.4) / 100.0
    return float(min(BODY_FAT_RANGE[1], max(BODY_FAT_RANGE[0], bf)))


def body_density(bmi: float, age_years: float, sex: float) -> float:
    """Whole-body density [kg/m^3] of the two-compartment model (Siri 1961) at `body_fat_fraction`."""
    f = body_fat_fraction(bmi, age_years, sex)
    return 1.0 / (f / FAT_DENSITY_KG_M3 + (1.0 - f) / LEAN_DENSITY_KG_M3)


def mesh_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Enclosed volume [m^3] of a closed, outward-wound triangle mesh [V, 3] m, [T, 3]: the divergence theorem,
    sum of a . (b x c) / 6 over the triangles (trimesh's ``Trimesh.volume`` to 1e-12, tests/test_body_shape.py;
    compiled: the calibration takes ~40 of them, and numpy's gathers cost 2-5 ms each)."""
    return float(_volume(np.ascontiguousarray(vertices, np.float64), np.ascontiguousarray(faces, np.int64)))


@numba.njit(cache=True, nogil=True)
def _volume(v, f):
    s = 0.0
    for k in range(f.shape[0]):
        a, b, c = v[f[k, 0]], v[f[k, 1]], v[f[k, 2]]
        s += (a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2])
              + a[2] * (b[0] * c[1] - b[1] * c[0]))
    return s / 6.0


def mesh_bmi(vertices: np.ndarray, faces: np.ndarray, age_years: float, sex: float) -> float:
    """BMI [kg/m^2] of a standing body mesh (m, z up): mass = volume x `body_density`(BMI), solved for the
    BMI at which the two agree (density falls slowly with BMI, so there is one)."""
    v = mesh_volume(vertices, faces)
    h = float(np.ptp(vertices[:, 2]))
    return float(brentq(lambda b: v * body_density(b, age_years, sex) / h**2 - b, 1.0, 200.0, xtol=1e-10))


def _height_slider(m: MacroValues, stature: float) -> float:
    """The height slider at which body `m` is `stature` m tall (0 or 1 beyond the slider's range)."""
    z = shaped_points_many([m._replace(height=h) for h in (0.0, 0.5, 1.0)])[:, :N_SKIN, 2]
    ends = [float(np.ptp(v)) for v in z]
    if stature <= ends[0]:
        return 0.0
    if stature >= ends[2]:
        return 1.0
    k = 0 if stature < ends[1] else 1
    a, b = z[k], z[k + 1] - z[k]  # exact: the points are affine in the slider on each half (body_targets)
    t = brentq(lambda t: float(np.ptp(a + t * b)) - stature, 0.0, 1.0, xtol=1e-9)
    return 0.5 * (k + t)


class _Grid:
    """The skin of body `m` at the nine muscle x weight anchors: every target's weight is linear in one
    muscle and one weight anchor weight, so any (muscle, weight) body is their bilinear blend."""

    def __init__(self, m: MacroValues, stature: float, density: float):
        self.stature, self.density = stature, density
        anchors = [m._replace(muscle=u, weight=w) for u in (0.0, 0.5, 1.0) for w in (0.0, 0.5, 1.0)]
        self.skin = shaped_points_many(anchors)[:, :N_SKIN].reshape(3, 3, N_SKIN, 3)
        self.faces = np.ascontiguousarray(load_avatar("full").faces, np.int64)

    def points(self, muscle: float, weight: float) -> np.ndarray:
        c = np.outer(anchor_weights(muscle), anchor_weights(weight))
        out = np.zeros((N_SKIN, 3))
        for i, j in zip(*np.nonzero(c)):  # at most four anchors
            out += c[i, j] * self.skin[i, j]
        return out

    def bmi(self, muscle: float, weight: float) -> float:
        """BMI [kg/m^2] of the (muscle, weight) body scaled to the stature."""
        p = self.points(muscle, weight)
        s = self.stature / float(np.ptp(p[:, 2]))
        return float(_volume(p, self.faces)) * s**3 * self.density / self.stature**2

    def reaches(self, muscle: float, bmi: float, w_max: float = 1.0) -> bool:
        """Whether some weight slider in [0, `w_max`] gives `bmi` at this muscle."""
        return self.bmi(muscle, 0.0) <= bmi <= self.bmi(muscle, w_max)

    def weight(self, muscle: float, bmi: float, w_max: float = 1.0) -> float:
        """The weight slider (0..`w_max`) giving `bmi` (BMI grows with it; call `reaches` first)."""
        return float(brentq(lambda w: self.bmi(muscle, w) - bmi, 0.0, w_max, xtol=1e-7))


@lru_cache(maxsize=256)
def fit_macro(sex: float, age_years: float, bmi: float, muscle: float, proportions: float,
              stature: float) -> MacroValues:
    """MakeHuman's macro values for a body of these anthropometrics (see the module doc).

    The muscle is the requested one if MakeHuman's anchors reach `bmi` there (weight 0..1), else the nearest
    muscle that does; if none does (BMIs above every maxweight anchor), the muscle whose maxweight body is
    heaviest, with the weight extrapolated up to `WEIGHT_MAX`.

    Args:
        sex: 0 female .. 1 male. age_years: years (>= 18). bmi: kg/m^2. muscle, proportions: 0..1.
        stature: standing height [m] the body will be scaled to.

    Raises:
        InputError: `bmi` is beyond the model's reach at this stature, sex, age and proportions.
    """
    base = MacroValues(gender=float(sex), age=age_value(age_years), muscle=float(muscle), weight=0.5,
                       proportions=float(proportions))
    base = base._replace(height=_height_slider(base, stature))
    g = _Grid(base, stature, body_density(bmi, age_years, sex))
    if g.reaches(muscle, bmi):
        return base._replace(weight=g.weight(muscle, bmi))
    grid = np.linspace(0.0, 1.0, _MUSCLE_GRID)
    ok = [g.reaches(float(u), bmi) for u in grid]
    if any(ok):
        good = float(min((u for u, k in zip(grid, ok) if k), key=lambda u: abs(u - muscle)))
        bad = float(muscle)  # a boundary of the muscles that reach the BMI lies between the two
        for _ in range(_BISECTIONS):
            mid = 0.5 * (good + bad)
            good, bad = (mid, bad) if g.reaches(mid, bmi) else (good, mid)
        return base._replace(muscle=good, weight=g.weight(good, bmi))
    heavy = float(grid[int(np.argmax([g.bmi(float(u), 1.0) for u in grid]))])
    if not g.reaches(heavy, bmi, WEIGHT_MAX):
        lo, hi = min(g.bmi(float(u), 0.0) for u in grid), g.bmi(heavy, WEIGHT_MAX)
        raise InputError(f"BMI {bmi:.1f} is outside what the body shape model reaches at {stature:.2f} m "
                         f"({lo:.1f}-{hi:.1f} kg/m^2 for this sex, age and proportions)")
    return base._replace(muscle=heavy, weight=g.weight(heavy, bmi, WEIGHT_MAX))


__all__ = ["age_value", "body_fat_fraction", "body_density", "mesh_volume", "mesh_bmi", "fit_macro",
           "YOUNG_YEARS", "OLD_YEARS"]
