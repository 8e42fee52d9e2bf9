"""Training-time augmentation of classifier inputs: random time shift, time stretch, velocity scale, dB jitter.

Why: a model trained on simulation only learnt *where* each activity sits in its clip and the exact
pace and velocity scale of the simulated bodies (issue 27: real images shifted by -1.5 s fell from 92 % to
67 % accuracy, velocities x1.25 to 83 %). Augmentation makes the training images vary the way deployments
vary, so the model cannot rely on those cues. The ranges are chosen from physical and deployment
variation (documented per field), never fitted to real data.

Geometry: the input image [V, T] (`processing.classifier.preprocess`) has velocity bins spanning
[-v_range, +v_range] symmetric about 0 (rows) and time bins (columns). Shift, stretch and velocity scale
are one affine resampling per sample (`resample`, `torch.nn.functional.affine_grid` / `grid_sample`,
bilinear) with ``align_corners=False``: normalised coordinates -1 and +1 are the outer *edges* of the
first and last bins, exactly how the preprocessing defines its bins (edges at +-v_range), so scaling by s
about the centre maps a pixel at velocity v to s*v and a shift of k columns is exactly k bins. Every
channel (radar link) of a sample gets the same geometric transform (the radars saw one motion).

What enters the image from outside (before the first / after the last column, beyond +-v_range) is the
sample's own noise floor: each channel's quietest column (lowest mean), velocity-scaled like the rest,
replicated - not zeros, which would be a black band no recording has.

Intensity: the dB image value is ``1 + dB / floor_db`` (0 = floor_db below the peak). The jitter multiplies
the dB values by ``g = floor_db / (floor_db + d)`` (the visible floor moved by d dB) and adds an offset of
o dB, then clips to [0, 1]; for ``scale='linear'`` the same operation in the linear domain is
``clip(value**g * 10**(o/10), 0, 1)``.

Randomness comes only from the caller's `torch.Generator` and the same number of draws is taken for every
batch whatever the settings, so a seed gives the same augmented batches.
"""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from pydantic import BaseModel, ConfigDict, Field, model_validator

from processing.classifier.preprocess import PreprocessConfig
from processing.errors import InputError

_RANGE = tuple[float, float]


class AugmentConfig(BaseModel):
    """Random training-time transforms of the input images (seconds, factors, dB). Off unless `on`.

    `AugmentConfig()` is off (training as without augmentation); `AugmentConfig(on=True)` applies the
    defaults below. A transform whose range is the identity (shift 0, range (1, 1), 0 dB) is skipped.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    on: bool = Field(False, description="apply augmentation to training batches (off: the batches are untouched)")
    p: float = Field(0.5, ge=0, le=1, description="probability with which each transform is applied to a sample, "
                     "independently (0.5: half the samples keep each nominal property, the model still sees "
                     "the simulated geometry as often as a variant of it)")
    # recording start vs. the activity: a person reacting to a 'go' (0.2-0.5 s), a hand-started recording and
    # the power-centroid centring of 'window' mode for activities that are asymmetric in time (sit: motion
    # then stillness) move the activity by about a second in a 5-10 s clip
    shift_s: float = Field(1.0, ge=0, le=60, description="maximum time shift either way [s], uniform; for "
                           "time_mode 'window' a column is window_s / n_time s, for 'resample' / 'active' "
                           "(no fixed time scale) the image width is taken as nominal_width_s")
    nominal_width_s: float = Field(6.0, gt=0, le=3600, description="time_mode 'resample' / 'active': seconds "
                                   "the image width is taken to span, so the shift is shift_s / nominal_width_s "
                                   "of the width (default 6 s = the default window_s: the same fraction, 1/6, in "
                                   "every mode)")
    # people differ in pace: self-selected gait speed of adults spans ~0.8-1.6 m/s, older people are slower,
    # and sit-down / pick-up durations vary by tens of percent between and within subjects
    stretch: _RANGE = Field((0.75, 4 / 3), description="time stretch factor range (lo, hi), log-uniform; > 1: "
                            "slower (longer) activity, about the image centre")
    # velocities scale with body size (limb speed at equal cadence ~ height: 1.5-1.95 m is +-13 %), walking
    # speed and the aspect angle (radial velocity = v cos(angle)); log-symmetric 0.8-1.25
    vscale: _RANGE = Field((0.8, 1.25), description="velocity scale factor range (lo, hi), log-uniform; about "
                           "0 m/s (the centre row)")
    # a different radar / STFT window / noise figure shows a few dB more or less dynamic range above the noise
    db_floor: float = Field(5.0, ge=0, le=100, description="the visible floor moved by up to +- this [dB] "
                            "(a gain of the dB scale, floor_db / (floor_db + d))")
    # the per-sample peak normalisation follows one strongest pixel: scalloping of the Doppler bins (~1.4 dB
    # for a Hann window) and speckle of the strongest scatterer move it by a dB or two
    db_offset: float = Field(2.0, ge=0, le=100, description="offset of every pixel by up to +- this [dB] "
                             "(peak-normalisation error; clipped to [0, 1] afterwards)")

    # receiver noise made visible: the body's SNR falls by 28 dB from 1 to 5 m (R^4) and with the radar's
    # gain, so a recording's noise may sit anywhere from far below the display's 40 dB span to well inside it;
    # a periodogram's noise is exponentially distributed per pixel (chi-square, 2 degrees of freedom)
    noise_db: _RANGE | None = Field((-40.0, -20.0), description="receiver-noise level range [dB re the sample's "
                                    "peak pixel] (lo, hi), uniform; exponential speckle per pixel; None: off")

    @model_validator(mode="after")
    def _ranges(self) -> "AugmentConfig":
        if self.noise_db is not None and not -120 <= self.noise_db[0] <= self.noise_db[1] <= 0:
            raise InputError(f"augment noise_db must be a range -120 <= lo <= hi <= 0 dB, got {self.noise_db}")
        for name in ("stretch", "vscale"):
            lo, hi = getattr(self, name)
            if not 0.25 <= lo <= hi <= 4.0:
                raise InputError(f"augment {name} must be a range 0.25 <= lo <= hi <= 4, got ({lo:g}, {hi:g})")
        return self

    @property
    def enabled(self) -> bool:
        """True when a training batch would actually change (on, p > 0 and some transform not the identity)."""
        return self.on and self.p > 0 and (self.shift_s > 0 or self.stretch != (1.0, 1.0) or self.noise_db is not None
                                           or self.vscale != (1.0, 1.0) or self.db_floor > 0 or self.db_offset > 0)

    def max_shift_columns(self, preprocess_cfg: PreprocessConfig) -> float:
        """`shift_s` in input columns (see the field's description)."""
        span = preprocess_cfg.window_s if preprocess_cfg.time_mode == "window" else self.nominal_width_s
        return self.shift_s / span * preprocess_cfg.n_time


# Named sets of transforms (`rtchannel train --augment NAME`): fields that differ from AugmentConfig's defaults.
# "scale" keeps only the velocity scale and the time stretch. With the spectrogram input (--intensity power) the
# others cost accuracy on real images (docs/results.md, "Scale-only augmentation"): a shift cuts activities
# (a pick whose stoop left the clip is a stand-up) and the noise and dB transforms answer a floor problem that
# the spectrogram does not have.
PRESETS: dict[str, dict] = {
    "all": {},
    "scale": {"shift_s": 0.0, "db_floor": 0.0, "db_offset": 0.0, "noise_db": None},
}


def noise_floor_columns(x: torch.Tensor) -> torch.Tensor:
    """Each channel's quietest column (lowest mean over velocity) [B, C, V, 1] of x [B, C, V, T]."""
    idx = x.mean(dim=2).argmin(dim=-1)  # [B, C]
    return torch.gather(x, 3, idx[:, :, None, None].expand(-1, -1, x.shape[2], 1))


def resample(x: torch.Tensor, shift_cols, stretch, vscale, fill: torch.Tensor | None = None) -> torch.Tensor:
    """x [B, C, V, T] resampled: content moved by `shift_cols` columns (> 0: later), stretched in time by
    `stretch` about the centre column, velocities scaled by `vscale` about 0 (the centre row); per-sample
    tensors [B] (or scalars). Regions from outside the image take `fill` [B, C, V, 1] (default: each
    channel's quietest column, see `noise_floor_columns`), velocity-scaled the same way."""
    b, c, v, t = x.shape
    x = x.float()
    shift_cols, stretch, vscale = (torch.as_tensor(a, dtype=x.dtype).expand(b) for a in (shift_cols, stretch, vscale))
    theta = torch.zeros(b, 2, 3, dtype=x.dtype)
    # output normalised coords -> input: x_in = (x_out - 2k/T) / stretch, y_in = y_out / vscale
    theta[:, 0, 0] = 1 / stretch
    theta[:, 0, 2] = -(2 * shift_cols / t) / stretch
    theta[:, 1, 1] = 1 / vscale
    grid = F.affine_grid(theta, [b, c, v, t], align_corners=False)
    inside = F.grid_sample(torch.ones(b, 1, v, t, dtype=x.dtype), grid, mode="bilinear", padding_mode="zeros",
                           align_corners=False)
    img = F.grid_sample(x, grid, mode="bilinear", padding_mode="zeros", align_corners=False)
    fill = noise_floor_columns(x) if fill is None else fill.to(x.dtype)
    # the fill is constant in time; 'border' replicates its edge rows beyond +-v_range
    fill = F.grid_sample(fill.expand(b, c, v, t), grid, mode="bilinear", padding_mode="border", align_corners=False)
    # bilinear weights of outside neighbours (1 - inside) go to the fill: the image padded with its noise floor
    return img + (1 - inside) * fill


def _log_uniform(u: torch.Tensor, lo: float, hi: float) -> torch.Tensor:
    return torch.exp(math.log(lo) + u * (math.log(hi) - math.log(lo)))


def augment_batch(x: torch.Tensor, cfg: AugmentConfig, generator: torch.Generator,
                  preprocess_cfg: PreprocessConfig) -> torch.Tensor:
    """A randomly augmented copy of the training batch x [B, C, V, T] (values in [0, 1]); x itself if
    `cfg.enabled` is False (no random numbers drawn then). Deterministic given the generator's state."""
    if not cfg.enabled:
        return x
    if x.ndim != 4:
        raise InputError(f"augment_batch expects [B, C, V, T], got {tuple(x.shape)}")
    if cfg.db_floor >= preprocess_cfg.floor_db:
        raise InputError(f"augment db_floor ({cfg.db_floor:g} dB) must be less than the preprocessing's floor_db "
                         f"({preprocess_cfg.floor_db:g} dB)")
    b = x.shape[0]
    with torch.no_grad():
        # always the same draws, whatever the settings: 4 apply-flags and 5 values per sample
        apply = torch.rand(b, 4, generator=generator) < cfg.p
        u = torch.rand(b, 5, generator=generator, dtype=torch.float64)
        shift = torch.where(apply[:, 0], (2 * u[:, 0] - 1) * cfg.max_shift_columns(preprocess_cfg), 0.0)
        stretch = torch.where(apply[:, 1], _log_uniform(u[:, 1], *cfg.stretch), 1.0)
        vscale = torch.where(apply[:, 2], _log_uniform(u[:, 2], *cfg.vscale), 1.0)
        out = x.float()
        if bool(((shift != 0) | (stretch != 1) | (vscale != 1)).any()):
            geo = (shift != 0) | (stretch != 1) | (vscale != 1)
            out = out.clone()
            out[geo] = resample(out[geo], shift[geo].float(), stretch[geo].float(), vscale[geo].float())
        d = torch.where(apply[:, 3], (2 * u[:, 3] - 1) * cfg.db_floor, 0.0)
        o = torch.where(apply[:, 3], (2 * u[:, 4] - 1) * cfg.db_offset, 0.0)
        if bool(apply[:, 3].any()) and (cfg.db_floor > 0 or cfg.db_offset > 0):
            floor = preprocess_cfg.floor_db
            g = (floor / (floor + d)).float()[:, None, None, None]
            o = o.float()[:, None, None, None]
            if preprocess_cfg.scale == "db":
                out = 1 - (1 - out) * g + o / floor
            else:
                out = out.clamp(min=0) ** g * 10 ** (o / 10)
        # always drawn (the same number of draws whatever the settings): a flag, a level and the speckle
        noisy = torch.rand(b, generator=generator) < cfg.p
        level_u = torch.rand(b, generator=generator, dtype=torch.float64)
        speckle = -torch.log1p(-torch.rand(out.shape, generator=generator)).clamp(max=50.0)  # Exp(1)
        if cfg.noise_db is not None and bool(noisy.any()):
            out = add_noise(out, noisy, cfg.noise_db[0] + level_u * (cfg.noise_db[1] - cfg.noise_db[0]), speckle,
                            preprocess_cfg)
        return out.clamp(0.0, 1.0).to(x.dtype)


def add_noise(x: torch.Tensor, which: torch.Tensor, level_db: torch.Tensor, speckle: torch.Tensor,
              preprocess_cfg: PreprocessConfig) -> torch.Tensor:
    """x [B, C, V, T] (values in [0, 1] on the preprocessing's scale) with receiver noise added to the samples
    `which` [B]: power level_db [B] (dB re the peak pixel) times `speckle` [B, C, V, T] (mean 1) added in the
    linear power domain, the result renormalised to its peak and mapped back to the scale."""
    floor = preprocess_cfg.floor_db
    if preprocess_cfg.scale == "db":
        power = torch.where(x > 0, 10 ** ((x - 1) * floor / 10), torch.zeros_like(x))  # 0: below the floor
    else:
        power = x.clamp(min=0)
    noise = (10 ** (level_db.float() / 10))[:, None, None, None] * speckle
    p = torch.where(which[:, None, None, None], power + noise, power)
    p = p / p.amax(dim=(1, 2, 3), keepdim=True).clamp(min=1e-30)
    if preprocess_cfg.scale == "linear":
        return p
    return 1 + 10 * torch.log10(p.clamp(min=10 ** (-floor / 10))) / floor


__all__ = ["AugmentConfig", "add_noise", "augment_batch", "noise_floor_columns", "resample"]
