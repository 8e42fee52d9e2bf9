"""The physical layer of a dataset plan: link sets, radar kit, directions, antenna placement and tilt drawn per
item, and the room drawn per motion (pydantic models; a bad field is one error naming it)."""
from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from processing.dsp.signatures import DSPConfig
from processing.errors import InputError
from processing.radar.waveform import Waveform
from rtchannel.dataset.plan_fields import _NAME, Scalar, _Model, _per_activity, _within, for_activity, unique_names
from rtchannel.radar import Link, direction_angles

class LinkSet(_Model):
    """A named set of radar links (monostatic, bistatic or multistatic); positions before rotation [m]."""

    name: str = Field(pattern=_NAME)
    links: list[Link] = Field(min_length=1)

    @field_validator("links")
    @classmethod
    def _unique(cls, v):
        return unique_names(v, "link")


def _seed_link_set() -> list[LinkSet]:
    return [LinkSet(name="seed", links=[Link(name="radar1", tx=(3.0, 0.0, 1.1)),
                                         Link(name="radar2", tx=(0.0, -3.0, 1.1))])]


class RoomDraw(_Model):
    """A box room drawn per motion for the mesh backends (`rtchannel.scene.rooms`): it holds the person's
    spot with `person_clear_m` of free floor around it and every antenna of the motion's items, each wall a
    drawn `margin_m` beyond the farthest of them; walls `height_m` high. The points backend ignores it."""

    margin_m: Scalar = Field((0.3, 2.0), description="free space between a wall and the nearest antenna or the "
                             "person's free floor [m] (value or [low, high] drawn per wall)")
    person_clear_m: float = Field(2.0, ge=0.5, le=20, description="free floor around the person's spot [m] "
                                  "(a fall reaches ~1.3 h from where it starts)")
    height_m: Scalar = Field((2.4, 3.2), description="wall height [m] (value or [low, high])")

    @field_validator("margin_m")
    @classmethod
    def _margin(cls, v):
        return _within(v, 0.3, 20.0, "room.margin_m", " m")

    @field_validator("height_m")
    @classmethod
    def _wall_height(cls, v):
        return _within(v, 1.8, 20.0, "room.height_m", " m")

    def draw(self, antennas: np.ndarray, rng) -> str:
        """The room's scene name (``room:...``) around the person's spot (origin) and `antennas` [N, 3] (m)."""
        from rtchannel.scene.rooms import room_name

        pts = np.vstack([np.asarray(antennas, float)[:, :2], [[-self.person_clear_m, -self.person_clear_m],
                                                              [self.person_clear_m, self.person_clear_m]]])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        m = [float(rng.uniform(*self.margin_m)) if isinstance(self.margin_m, tuple) else float(self.margin_m)
             for _ in range(4)]
        h = float(rng.uniform(*self.height_m)) if isinstance(self.height_m, tuple) else float(self.height_m)
        h = max(h, float(np.max(np.asarray(antennas, float)[:, 2])) + 0.5)  # walls above the antennas
        return room_name(lo[0] - m[0], hi[0] + m[1], lo[1] - m[2], hi[1] + m[3], h)


def _value(v, rng) -> float:
    """A field's value: drawn uniformly from `rng` for a (low, high) range."""
    return float(rng.uniform(*v)) if isinstance(v, tuple) else float(v)


class AimDraw(_Model):
    """How the radar is aimed at the person: the boresight passes through a point on the person's vertical
    axis at `height_frac` x stature, plus an aiming error. The downtilt is then atan((h_antenna - h_aim) / d)
    + error for an antenna at height h_antenna and horizontal distance d (negative: tilted up), so a low
    radar near a tall person looks up and a high one looks down, as an operator aims it."""

    height_frac: Scalar = Field((0.45, 0.6), description="aim point height / stature: the trunk, from the hips "
                                "(~0.5 h) to the chest (~0.72 h); the body's centre of mass sits at ~0.55 h "
                                "(Winter, Biomechanics and Motor Control of Human Movement, 4th ed., table 4.1)")
    error_deg: Scalar = Field((-8.0, 8.0), description="aiming error in elevation [deg] (value or [low, high]): "
                              "aimed by eye and checked on the live display, the aim point stays inside the "
                              "half-power beam (a third of a 24 deg beam either way)")

    @field_validator("height_frac")
    @classmethod
    def _frac(cls, v):
        return _within(v, 0.0, 1.2, "aim.height_frac")

    @field_validator("error_deg")
    @classmethod
    def _err(cls, v):
        return _within(v, -45.0, 45.0, "aim.error_deg", " deg")

    def downtilt_deg(self, antenna: tuple, stature_m: float, rng) -> float:
        """The drawn downtilt [deg] of an antenna at `antenna` (x, y, z) [m] aimed at a person of stature
        `stature_m` [m] standing on the vertical through the origin, clipped to the antenna model's +-60 deg."""
        d = max(float(np.hypot(antenna[0], antenna[1])), 1e-6)
        aim = _value(self.height_frac, rng) * stature_m
        tilt = np.degrees(np.arctan2(float(antenna[2]) - aim, d)) + _value(self.error_deg, rng)
        return float(np.clip(tilt, -60.0, 60.0))


class BeamDraw(_Model):
    """The Yagis' beam drawn per placement: E-plane and H-plane half-power beamwidths, with the peak gain taken
    from them (`processing.radar.antenna.practical_gain_dbi`, Balanis eq. 2-27), so a wide beam never keeps a
    narrow beam's gain. A vertically polarised Yagi (elements vertical) has its E-plane in elevation; a
    horizontally polarised one in azimuth."""

    e_plane_deg: Scalar = Field((18.0, 40.0), description="E-plane HPBW [deg] (value or [low, high])")
    h_over_e: Scalar = Field((1.0, 1.3), description="H-plane HPBW / E-plane HPBW (a Yagi's H-plane is the "
                             "wider: the element pattern has no null there), capped at 170 deg")

    @field_validator("e_plane_deg")
    @classmethod
    def _e(cls, v):
        return _within(v, 5.0, 170.0, "beam.e_plane_deg", " deg")

    @field_validator("h_over_e")
    @classmethod
    def _ratio(cls, v):
        return _within(v, 1.0, 3.0, "beam.h_over_e")

    def draw(self, rng, polarization: str = "V") -> dict:
        """Antenna fields {hpbw_az_deg, hpbw_el_deg, peak_gain_dbi} of one drawn beam of a Yagi of linear
        `polarization` ("V": elements vertical, E-plane in elevation; "H": E-plane in azimuth)."""
        from processing.radar.antenna import practical_gain_dbi

        e = _value(self.e_plane_deg, rng)
        h = min(e * _value(self.h_over_e, rng), 170.0)
        az, el = (h, e) if polarization == "V" else (e, h)
        return {"hpbw_az_deg": az, "hpbw_el_deg": el, "peak_gain_dbi": practical_gain_dbi(az, el)}


class PhysicalLayer(_Model):
    """Physical-layer augmentation: directions (rotations of all antennas about z), waveforms, link sets."""

    directions: Literal["seed"] | list[int] | None = Field(
        None, description="seed directions 1..18 ('seed' = all 18); default when angles_deg is not given")
    angles_deg: list[float] | None = Field(None, min_length=1, description="rotation angles [deg] instead")
    waveforms: list[Waveform] = Field(default_factory=lambda: [Waveform()], min_length=1)
    dsp: DSPConfig = Field(default_factory=DSPConfig)
    link_sets: list[LinkSet] = Field(default_factory=_seed_link_set, min_length=1)
    radar: Literal["seed", "glasgow"] = Field("seed", description="radar kit: seed (Ancortek 2400T2R4 horns, "
                                              "24 GHz defaults) or glasgow (Radar.glasgow: 5.8 GHz 580AD Yagis "
                                              "looking horizontally at the z axis; waveform and DSP default to "
                                              "the Glasgow ones)")
    downtilt_deg: Scalar | None = Field(None, description="glasgow kit: beam tilt below horizontal [deg] "
                                        "(value or [low, high] drawn per item), -60..60")
    hpbw_el_deg: Scalar | None = Field(None, description="glasgow kit: elevation beamwidth of the Yagis [deg] "
                                       "(value or [low, high] drawn per item), 5..170")
    distance_m: Scalar | dict[str, Scalar] | None = Field(
        None, description="horizontal distance of every antenna from the person's spot (the walk centre) [m] (value "
        "or [low, high] drawn per item; or these per activity, '*': any other), 0.5..30; the link sets' antenna "
        "azimuths are kept. None: the link sets' positions")
    height_m: Scalar | None = Field(None, description="height of every antenna above the floor [m] (value or "
                                    "[low, high] drawn per item), 0.1..5. None: the link sets' heights")
    room: RoomDraw | None = Field(None, description="mesh backends: a box room drawn per motion around the "
                                  "person and its items' antennas (None: the backend's scene option)")
    aim: AimDraw | None = Field(None, description="glasgow kit: aim the beam at the person (tilt from the antenna "
                                "height, the distance and the stature, plus an aiming error) instead of drawing "
                                "downtilt_deg")
    beam: BeamDraw | None = Field(None, description="glasgow kit: draw the Yagis' E- and H-plane beamwidths and take "
                                  "the peak gain from them, instead of hpbw_el_deg")
    polarization: list[Literal["V", "H"]] | None = Field(
        None, min_length=1, description="glasgow kit: the antennas' linear polarisation, drawn uniformly from this "
        "list per placement (both antennas of a link alike); None: the kit's default (V)")

    @field_validator("distance_m")
    @classmethod
    def _distance_range(cls, v):
        for k, x in (_per_activity(v, "distance_m") if isinstance(v, dict) else {"": v}).items():
            if x is not None:
                _within(x, 0.5, 30.0, f"distance_m.{k}" if k else "distance_m", " m")
        return v

    @field_validator("height_m")
    @classmethod
    def _height_range(cls, v):
        return v if v is None else _within(v, 0.1, 5.0, "height_m", " m")

    @field_validator("downtilt_deg")
    @classmethod
    def _tilt_range(cls, v):
        return v if v is None else _within(v, -60.0, 60.0, "downtilt_deg", " deg")

    @field_validator("hpbw_el_deg")
    @classmethod
    def _hpbw_range(cls, v):
        return v if v is None else _within(v, 5.0, 170.0, "hpbw_el_deg", " deg")

    @model_validator(mode="before")
    @classmethod
    def _radar_defaults(cls, data):
        if isinstance(data, dict) and data.get("radar") == "glasgow":
            from rtchannel.radar import GLASGOW_WAVEFORM, glasgow_dsp

            data = {"waveforms": [GLASGOW_WAVEFORM], "dsp": glasgow_dsp(), **data}
        return data

    def kit(self, links: list[Link]) -> dict:
        """Antenna and receiver fields of the radar dict for a link set (empty: RadarConfig's defaults)."""
        if self.radar != "glasgow":
            return {}
        from rtchannel.radar import RadarConfig

        r = RadarConfig.glasgow(height_m=links[0].tx_pos[2], distance_m=2.5)  # boresight at the antenna height
        return {"antenna": r.antenna.model_dump(mode="json"),
                "receiver": None if r.receiver is None else r.receiver.model_dump(mode="json")}

    @model_validator(mode="after")
    def _angles(self) -> "PhysicalLayer":
        if self.directions is not None and self.angles_deg is not None:
            raise InputError("give either 'directions' or 'angles_deg', not both")
        if self.radar != "glasgow" and any(x is not None for x in (self.downtilt_deg, self.hpbw_el_deg, self.aim,
                                                                     self.beam, self.polarization)):
            raise InputError("downtilt_deg, hpbw_el_deg, aim, beam and polarization apply to radar: glasgow (the "
                             "seed's horns are fixed)")
        if self.aim is not None and self.downtilt_deg is not None:
            raise InputError("give either 'aim' or 'downtilt_deg', not both")
        if self.beam is not None and self.hpbw_el_deg is not None:
            raise InputError("give either 'beam' or 'hpbw_el_deg', not both")
        if isinstance(self.directions, list):
            for d in self.directions:
                direction_angles(d)  # raises a ValueError naming the bad direction
        names = [s.name for s in self.link_sets]
        if len(set(names)) != len(names):
            raise InputError(f"link set names must be unique, got {names}")
        return self

    def placed(self, links: list[Link], activity: str, rng) -> list[Link]:
        """`links` with distance_m and height_m drawn from `rng` (each antenna moved along its azimuth to the
        drawn horizontal distance, at the drawn height); unchanged where neither is set."""
        d = for_activity(self.distance_m, activity)
        h = None if self.height_m is None else float(rng.uniform(*self.height_m)) if isinstance(
            self.height_m, tuple) else float(self.height_m)
        d = None if d is None else float(rng.uniform(*d)) if isinstance(d, tuple) else float(d)
        if d is None and h is None:
            return links

        def move(p):
            if p is None:
                return None
            xy = np.asarray(p[:2], float)
            r = float(np.hypot(*xy))
            if d is not None and r == 0:
                raise InputError("distance_m needs antennas off the vertical through the person's spot")
            xy = xy if d is None else xy * (d / r)
            return (float(xy[0]), float(xy[1]), float(p[2] if h is None else h))
        return [link.model_copy(update={"tx": move(link.tx), "rx": move(link.rx)}) for link in links]

    def rotations(self) -> list[tuple[float, int | None]]:
        """(rotation angle [deg], seed direction or None) per physical direction."""
        if self.angles_deg is not None:
            return [(float(a), None) for a in self.angles_deg]
        dirs = self.directions if isinstance(self.directions, list) else list(range(1, 19))  # None or "seed": all
        return [(direction_angles(d)[0], d) for d in dirs]
