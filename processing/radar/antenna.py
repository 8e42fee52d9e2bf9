"""Antenna power patterns (scalar) with a linear polarisation, and their orientation in the room.

Scale: backends give path coefficients a with |a|^2 = P_r / P_t for isotropic unit-gain antennas. A real
link multiplies each path by the antennas' amplitude factors,

    a  ->  a * sqrt(G_tx(u_tx)) * sqrt(G_rx(u_rx)),   `link_gain` / `gain` return these square roots,

where u_tx is the direction in which the path leaves the transmitter and u_rx the direction from which it
reaches the receiver (both pointing away from the antenna). For a direct scatterer path both are "towards
the scatterer"; for a wall-image path pass the scatterer's mirror image (it lies on the departing ray).

Local frame of an antenna at position p: x' = boresight (a unit vector, or the unit vector from p to
`look_at`), z' = the component of `up` orthogonal to x' (local "up"), y' = z' x x'. This is Sionna RT's
convention (a radio device's local x axis is its boresight; `look_at` keeps the world z axis up, roll 0),
so `sionna_orientation` turns the frame into Sionna's (yaw, pitch, roll).

Patterns, with psi the angle off boresight and chi the roll angle about boresight measured from y'
towards z' (chi = 0: the azimuth plane, chi = 90 deg: the elevation plane):

* ``isotropic``: G = 1 (0 dBi).
* ``gaussian`` (horn): G = G0 max(exp(-4 ln2 psi^2 (cos^2 chi / HPBW_az^2 + sin^2 chi / HPBW_el^2)), floor).
  In the azimuth plane (el = 0) and the elevation plane this is exactly the textbook form
  G0 exp(-4 ln2 ((az/HPBW_az)^2 + (el/HPBW_el)^2)); off the principal planes it uses the true angle off
  boresight rather than az/el, which stays regular at every direction (az/el compresses near the zenith
  and makes the pattern depend on the choice of "up" for a symmetric beam).
* ``yagi`` (end-fire): G = G0 max(cos^n psi [front half], 10^(-FB/10) |cos psi| [back half], floor), with
  n(chi) = n_az cos^2 chi + n_el sin^2 chi and n = ln(1/2) / ln(cos(HPBW/2)), so the half-power points
  and the front-to-back ratio FB are exact in the principal planes.

G0 is `peak_gain_dbi` if given, else the pattern's directivity 4 pi / integral of the normalised
pattern over the sphere (lossless antenna; `directivity_dbi`). For comparison, the closed forms are
Kraus's G ~ 41253 eta / (HPBW_az HPBW_el) [deg^2] (`kraus_gain_dbi`) and, for a narrow Gaussian beam
without floor, D = 16 ln2 / (HPBW_az HPBW_el) [rad^2] = 36410 / (HPBW_az HPBW_el) [deg^2].

A target at the antenna position has no direction; it is taken to lie on boresight (finite, never NaN).

Polarisation (``polarization``, every antenna): "V" (vertical, the default) or "H" (horizontal), Sionna RT's
spelling. The patterns above are power patterns, the same for both; the polarisation decides how walls, the
floor and surfaces reflect the wave (`rtchannel.backends.surface_scattering`). The field of a "V" antenna is
along theta-hat, of an "H" antenna along phi-hat, taken about the world z axis in the mesh backends (exact
for an untilted antenna; Sionna RT takes them about the tilted local z', a difference of order the tilt).
A link is modelled co-polarised: both of its antennas must have the same polarisation.
"""
from __future__ import annotations

import math
from functools import lru_cache
from types import SimpleNamespace
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, field_validator, model_validator

from processing.errors import InputError
from processing.summary import settings_repr

Vec3 = tuple[float, float, float]
_TINY = 1e-30  # below this squared sine a direction counts as on the boresight axis (float32-safe)
_LN2 = math.log(2.0)
POLARIZATIONS = ("V", "H")  # linear polarisations, Sionna RT's spelling: vertical (theta-hat), horizontal (phi-hat)

NUMPY_OPS = SimpleNamespace(sin=np.sin, cos=np.cos, exp=np.exp, sqrt=np.sqrt, arctan2=np.arctan2,
                            maximum=np.maximum, power=np.power, where=np.where)
"""Array operations `local_power_gain` uses. For Dr.Jit (Sionna RT) pass
``SimpleNamespace(sin=dr.sin, cos=dr.cos, exp=dr.exp, sqrt=dr.sqrt, arctan2=dr.atan2,
maximum=dr.maximum, power=dr.power, where=dr.select)``."""


def _rot_z(angle_deg: float) -> np.ndarray:
    a = math.radians(angle_deg)
    return np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])


class _Antenna(BaseModel):
    """Orientation shared by all patterns. Positions and directions in the project frame (z up, m)."""

    __repr__ = settings_repr  # the fields set away from their defaults

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    boresight: Vec3 | None = Field(None, description="boresight direction (any length > 0); or give look_at")
    look_at: Vec3 | None = Field(None, description="point the boresight aims at [m]; or give boresight")
    up: Vec3 = Field((0.0, 0.0, 1.0), description="reference 'up' for azimuth/elevation (any length > 0)")
    downtilt_deg: float = Field(0.0, ge=-60.0, le=60.0, description="beam tilt below the direction given by "
                                "boresight/look_at [deg], in the vertical plane through it (negative: uptilt). "
                                "Room radars are tilted by hand, typically a few to 20 deg down from a "
                                "tripod; +-60 bounds what keeps a person in a forward beam")
    polarization: str = Field("V", description="linear polarisation: 'V' (vertical, E along theta-hat) or 'H' "
                              "(horizontal, E along phi-hat); kits rarely publish it, a Yagi mounted flat is H")

    @field_validator("polarization", mode="before")
    @classmethod
    def _check_polarization(cls, v):
        if v not in POLARIZATIONS:
            raise InputError(f"antenna polarization must be 'V' (vertical) or 'H' (horizontal), got {v!r}")
        return v

    @model_validator(mode="after")
    def _check_orientation(self):
        if self.boresight is not None and self.look_at is not None:
            raise InputError("boresight and look_at: give one of them, not both")
        if np.linalg.norm(self.up) == 0:
            raise InputError("up must be a non-zero vector")
        if self.boresight is not None:
            b = np.asarray(self.boresight, float)
            if np.linalg.norm(b) == 0:
                raise InputError("boresight must be a non-zero vector")
            _check_not_parallel(b, np.asarray(self.up, float))
        return self

    def rotated_about_z(self, angle_deg: float):
        """This antenna with boresight, look-at point and up rotated by `angle_deg` (counter-clockwise
        seen from above) about the world z axis through the origin, as `RadarConfig.rotated` turns the
        antenna positions. A look-at point must turn with the antennas unless it lies on the z axis."""
        rz = _rot_z(angle_deg)

        def rot(v):
            return None if v is None else tuple(float(x) for x in rz @ np.asarray(v, float))

        return self.model_copy(update={"boresight": rot(self.boresight), "look_at": rot(self.look_at),
                                       "up": rot(self.up)})

    def boresight_unit(self, position) -> np.ndarray:
        """Unit boresight vector [3] of this antenna placed at `position` [3] (m)."""
        p = np.asarray(position, float)
        if self.boresight is not None:
            b = np.asarray(self.boresight, float)
        elif self.look_at is not None:
            b = np.asarray(self.look_at, float) - p
            if np.linalg.norm(b) < 1e-9:
                raise InputError(f"look_at {self.look_at} coincides with the antenna position {tuple(p)}: "
                                 "the boresight is undefined")
        else:
            b = np.array([1.0, 0.0, 0.0])  # isotropic antennas need no orientation
        b = b / np.linalg.norm(b)
        if self.downtilt_deg:
            up = np.asarray(self.up, float) / np.linalg.norm(self.up)
            h = b - (b @ up) * up  # horizontal part: the tilt keeps the azimuth
            if np.linalg.norm(h) < 1e-9:
                raise InputError("downtilt_deg needs a boresight that is not parallel to up")
            h /= np.linalg.norm(h)
            el = math.asin(max(-1.0, min(1.0, float(b @ up)))) - math.radians(self.downtilt_deg)
            b = math.cos(el) * h + math.sin(el) * up
        return b

    def frame(self, position) -> np.ndarray:
        """Rotation [3, 3] whose columns are the local axes x' (boresight), y', z' (up) in world
        coordinates; local components of a world vector d are ``d @ frame``."""
        x = self.boresight_unit(position)
        up = np.asarray(self.up, float)
        _check_not_parallel(x, up)
        z = up - (up @ x) * x
        z /= np.linalg.norm(z)
        return np.stack([x, np.cross(z, x), z], axis=1)


def _check_not_parallel(b: np.ndarray, up: np.ndarray) -> None:
    s = np.linalg.norm(np.cross(b, up)) / (np.linalg.norm(b) * np.linalg.norm(up))
    if s < 1e-6:
        raise InputError("boresight is parallel to up: the antenna's azimuth/elevation planes are undefined "
                         "(choose another up vector)")


class Isotropic(_Antenna):
    """Unit gain in every direction (0 dBi); the backends' native scale."""

    kind: Literal["isotropic"] = "isotropic"


class _Directional(_Antenna):
    peak_gain_dbi: float | None = Field(
        None, ge=0.0, le=50.0, description="boresight gain [dBi]; default: the pattern's directivity "
        "(lossless). Bounds: a directional antenna has >= 0 dBi; > 50 dBi is a large dish, not a room radar")
    floor_db: float = Field(
        30.0, ge=3.0, le=80.0, description="side/back-lobe floor [dB below peak]; >= 3 dB so the half-power "
        "beam exists, <= 80 dB because no real antenna is that clean and the pattern must never reach 0")

    @model_validator(mode="after")
    def _needs_orientation(self):
        if self.boresight is None and self.look_at is None:
            # every concrete subclass declares `kind` (a field of its own, so not declared here)
            raise InputError(f"a {self.kind} antenna needs boresight or look_at")  # type: ignore[attr-defined]
        return self


class GaussianBeam(_Directional):
    """Horn-like Gaussian main beam with an elliptical cross-section and a constant floor."""

    kind: Literal["gaussian"] = "gaussian"
    hpbw_az_deg: float = Field(ge=1.0, le=180.0, description="half-power beamwidth in the azimuth plane "
                               "[deg]; 1..180 (a 1-deg beam is already a metre-sized aperture at 24 GHz; "
                               "beyond 180 the half-power points would lie behind the antenna)")
    hpbw_el_deg: float = Field(ge=1.0, le=180.0, description="half-power beamwidth in the elevation plane "
                               "[deg]; 1..180")


class YagiBeam(_Directional):
    """End-fire (Yagi-Uda) pattern: cos^n main lobe, cosine back lobe at the front-to-back ratio."""

    kind: Literal["yagi"] = "yagi"
    hpbw_az_deg: float = Field(ge=5.0, le=170.0, description="half-power beamwidth in the azimuth plane "
                               "[deg]; 5..170 (a cos^n lobe needs HPBW < 180; real Yagis are >= 5 deg)")
    hpbw_el_deg: float = Field(ge=5.0, le=170.0, description="half-power beamwidth in the elevation plane [deg]")
    front_to_back_db: float = Field(20.0, ge=3.0, le=60.0, description="peak over the gain straight behind "
                                    "[dB]; 3..60 (typical Yagis: 15-25 dB)")

    @model_validator(mode="after")
    def _back_above_floor(self):
        if self.front_to_back_db > self.floor_db:
            raise InputError(f"front_to_back_db ({self.front_to_back_db}) exceeds floor_db ({self.floor_db}): "
                             "the floor would hide the back lobe; lower front_to_back_db or raise floor_db")
        return self


AntennaPattern = Annotated[Union[Isotropic, GaussianBeam, YagiBeam], Field(discriminator="kind")]
_ADAPTER = TypeAdapter(AntennaPattern)


def parse_antenna(data) -> Isotropic | GaussianBeam | YagiBeam:
    """An antenna from a dict (e.g. a YAML block with `kind`); pydantic's ValidationError names bad fields."""
    return _ADAPTER.validate_python(data)


def _cos_exponent(hpbw_deg: float) -> float:
    return math.log(0.5) / math.log(math.cos(math.radians(hpbw_deg) / 2))


def _normalised(spec, x, y, z, xp):
    """Pattern / peak (max 1) for local unit direction components x (along boresight), y, z."""
    if spec.kind == "isotropic":
        return 1.0 + 0.0 * x
    s2 = y * y + z * z
    axis = s2 < _TINY
    den = xp.maximum(s2, _TINY)
    floor = 10.0 ** (-spec.floor_db / 10.0)
    if spec.kind == "gaussian":
        wa, we = math.radians(spec.hpbw_az_deg) ** -2, math.radians(spec.hpbw_el_deg) ** -2
        psi = xp.arctan2(xp.sqrt(s2), x)
        q = xp.where(axis, wa, (y * y * wa + z * z * we) / den)
        g = xp.exp(-4.0 * _LN2 * psi * psi * q)
    else:
        na, ne = _cos_exponent(spec.hpbw_az_deg), _cos_exponent(spec.hpbw_el_deg)
        n = xp.where(axis, na, (y * y * na + z * z * ne) / den)
        back = 10.0 ** (-spec.front_to_back_db / 10.0) * xp.maximum(-x, 0.0)
        g = xp.maximum(xp.power(xp.maximum(x, 0.0), n), back)
    return xp.maximum(g, floor)


# Directivities of the shipped antennas' shapes as `_directivity` computes them on a 2-million-point grid
# (0.15-0.25 s per shape: a tenth of the whole `rtchannel simulate --backend points` process). Tabulated, the
# default radar costs nothing at start-up and gets the same value on every machine (numpy's vectorised
# exp/arctan2 may differ in the last bit between CPUs). tests/test_antenna.py recomputes every entry.
_TABULATED = {
    # ANCORTEK_2400T2R4 (the default radar's horns)
    ("gaussian", (("floor_db", 30.0), ("hpbw_az_deg", 30.0), ("hpbw_el_deg", 30.0), ("kind", "gaussian"))):
        39.78687945076156,
}


def _directivity_params(spec) -> tuple[str, tuple]:
    """The key of a pattern's shape: (kind, sorted shape parameters without orientation and peak gain)."""
    orientation = {"boresight", "look_at", "up", "downtilt_deg", "polarization"}  # none changes the power pattern
    return spec.kind, tuple(sorted(spec.model_dump(exclude=orientation | {"peak_gain_dbi"}).items()))


@lru_cache(maxsize=64)
def _directivity(kind: str, params: tuple) -> float:
    from scipy.integrate import simpson  # only for shapes not in `_TABULATED`

    shapes: dict[str, type[GaussianBeam] | type[YagiBeam]] = {"gaussian": GaussianBeam, "yagi": YagiBeam}
    cls = shapes[kind]
    spec = cls.model_validate(dict(params, boresight=(1.0, 0.0, 0.0)))
    psi = np.linspace(0.0, np.pi, 8193)
    chi = np.linspace(0.0, 2 * np.pi, 256, endpoint=False)  # periodic: the plain mean is spectrally exact
    p, c = np.meshgrid(psi, chi, indexing="ij")
    g = _normalised(spec, np.cos(p), np.sin(p) * np.cos(c), np.sin(p) * np.sin(c), NUMPY_OPS)
    solid_angle = simpson(g.mean(axis=1) * np.sin(psi), x=psi) * 2 * np.pi
    return 4 * np.pi / solid_angle


def directivity_dbi(spec) -> float:
    """Directivity [dBi] of the pattern's shape: 10 log10(4 pi / integral of G/G0 over the sphere)."""
    if spec.kind == "isotropic":
        return 0.0
    key = _directivity_params(spec)
    d = _TABULATED.get(key)
    return 10 * math.log10(_directivity(*key) if d is None else d)


def peak_gain_dbi(spec) -> float:
    """Boresight gain G0 [dBi]: `peak_gain_dbi` if set, else the directivity (lossless antenna)."""
    if spec.kind == "isotropic":
        return 0.0
    return spec.peak_gain_dbi if spec.peak_gain_dbi is not None else directivity_dbi(spec)


def kraus_gain_dbi(hpbw_az_deg: float, hpbw_el_deg: float, efficiency: float = 1.0) -> float:
    """Kraus's estimate 10 log10(41253 eta / (HPBW_az HPBW_el)) [dBi], beamwidths in degrees."""
    if not (0 < efficiency <= 1 and hpbw_az_deg > 0 and hpbw_el_deg > 0):
        raise InputError("kraus_gain_dbi needs beamwidths > 0 and 0 < efficiency <= 1")
    return 10 * math.log10(41252.96 * efficiency / (hpbw_az_deg * hpbw_el_deg))


def practical_gain_dbi(hpbw_az_deg: float, hpbw_el_deg: float) -> float:
    """Peak gain [dBi] of a practical antenna with these half-power beamwidths [deg]: 10 log10(32400 /
    (HPBW_az HPBW_el)) (Balanis, Antenna Theory, 4th ed., eq. 2-27: Kraus's 41253 with the side lobes and
    losses of real antennas). A 24 x 24 deg beam gives 17.5 dBi, the gain quoted for the Glasgow kit's Yagis,
    so drawing a beamwidth and taking the gain from it keeps the two consistent."""
    if not (0 < hpbw_az_deg <= 180 and 0 < hpbw_el_deg <= 180):
        raise InputError("practical_gain_dbi needs beamwidths in (0, 180] deg")
    return 10 * math.log10(32400.0 / (hpbw_az_deg * hpbw_el_deg))


def local_power_gain(spec, theta, phi, xp=NUMPY_OPS):
    """Linear power gain G(theta, phi) in the antenna's local frame, Sionna RT's convention: theta is the
    zenith angle from local z' (up), phi the azimuth from local x' (boresight) towards y' [rad].

    Written with `xp`'s functions only, so with Dr.Jit operations (see `NUMPY_OPS`) it runs inside
    Sionna: a vertically polarised Sionna pattern is ``C_theta = sqrt(G), C_phi = 0``.
    """
    st = xp.sin(theta)
    g0 = 10.0 ** (peak_gain_dbi(spec) / 10.0)
    return g0 * _normalised(spec, st * xp.cos(phi), st * xp.sin(phi), xp.cos(theta), xp)


def local_directions(spec, position, targets) -> np.ndarray:
    """Unit directions [..., 3] from `position` [3] to `targets` [..., 3] in the antenna's local frame
    (x' boresight, z' up); a target at the antenna position maps to boresight (1, 0, 0)."""
    d = np.asarray(targets, np.float64) - np.asarray(position, np.float64)
    r = np.linalg.norm(d, axis=-1, keepdims=True)
    local = (d @ spec.frame(position)) / np.where(r > 0, r, 1.0)
    return np.where(r > 0, local, np.array([1.0, 0.0, 0.0]))


def gain(spec, position, targets) -> np.ndarray:
    """Amplitude factor sqrt(G) [...] (float64) of the antenna at `position` [3] (m) towards `targets`
    [..., 3] (m): multiply path coefficients by it (once for the transmitter, once for the receiver)."""
    u = local_directions(spec, position, targets)
    g0 = 10.0 ** (peak_gain_dbi(spec) / 10.0)
    return np.sqrt(g0 * _normalised(spec, u[..., 0], u[..., 1], u[..., 2], NUMPY_OPS))


def polarization(spec) -> str:
    """Linear polarisation "V" or "H" of an antenna spec; None (an isotropic unit-gain antenna) is "V"."""
    return "V" if spec is None else spec.polarization


def link_polarization(tx_spec, rx_spec) -> str:
    """The polarisation of a co-polarised link; InputError when its two antennas differ (cross-polarised
    links are not modelled: every reflection is projected on the link's one polarisation)."""
    p_tx, p_rx = polarization(tx_spec), polarization(rx_spec)
    if p_tx != p_rx:
        raise InputError(f"a link's transmit ({p_tx}) and receive ({p_rx}) antennas must have the same "
                         "polarization (cross-polarised links are not modelled)")
    return p_tx


def link_gain(tx_spec, tx_position, rx_spec, rx_position, tx_targets, rx_targets=None) -> np.ndarray:
    """sqrt(G_tx G_rx) [...] for paths leaving the transmitter towards `tx_targets` [..., 3] and reaching
    the receiver from `rx_targets` (default: the same points, as for single-bounce scatterers)."""
    rx_targets = tx_targets if rx_targets is None else rx_targets
    return gain(tx_spec, tx_position, tx_targets) * gain(rx_spec, rx_position, rx_targets)


def sionna_orientation(spec, position) -> tuple[float, float, float]:
    """Sionna RT orientation (yaw, pitch, roll) [rad] whose rotation matrix Rz(yaw) Ry(pitch) Rx(roll)
    equals `spec.frame(position)`; set it on the Transmitter/Receiver and use `local_power_gain`."""
    f = spec.frame(position)
    return (math.atan2(f[1, 0], f[0, 0]), math.atan2(-f[2, 0], math.hypot(f[0, 0], f[1, 0])),
            math.atan2(f[2, 1], f[2, 2]))
