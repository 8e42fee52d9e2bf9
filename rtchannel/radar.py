"""Radar description: waveform, DSP, receiver, antennas and positions per link; the seed's 18 directions.

A *link* is one transmitter/receiver pair: monostatic (tx = rx, the seed's radars), bistatic (tx and
rx apart) or, by listing several links that share a transmitter, multistatic. Any number of links.
Positions are in the project frame (z up, metres). The seed's y-up positions (x, y, z) are (x, -z, y)
here: Radar 1 at (3, 0, 1.1) m and Radar 2 at (0, -3, 1.1) m.

Antennas (`processing.radar.antenna`): every link's transmitter and receiver has a pattern, the link's own
(`tx_antenna`, `rx_antenna`) or the radar's `antenna`. The default is the seed's kit (Ancortek SDR-KIT
2400T2R4, `processing.radar.receiver.ANCORTEK_2400T2R4`): 30-degree horns looking horizontally at the room
centre (0, 0, 1.1) m, and its receiver (transmit power, noise figure), so signatures carry the kit's
absolute thermal noise. `receiver=None` gives noiseless IQ; `antenna=Isotropic()` the unit-gain
antennas of the backends' native scale.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from processing.radar.antenna import AntennaPattern
from processing.dsp.signatures import DSPConfig
from processing.dsp.config import GLASGOW_DSP
from processing.radar.receiver import ANCORTEK_2400T2R4, ANCORTEK_580AD, ReceiverConfig
from processing.radar.waveform import Waveform
from processing.errors import InputError

MONOSTATIC_TOLERANCE_M = 0.1  # tx and rx closer than this share one position (co-located horns)
MAX_COORDINATE_M = 1e4  # antenna coordinates beyond 10 km are a unit mistake, not a room


class Link(BaseModel):
    """One transmitter -> receiver link. Positions in metres."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_\-]+$")
    tx: tuple[float, float, float]
    rx: tuple[float, float, float] | None = Field(None, description="receiver; default = tx (monostatic)")
    tx_antenna: AntennaPattern | None = Field(None, description="transmit antenna; default: the radar's")
    rx_antenna: AntennaPattern | None = Field(None, description="receive antenna; default: the radar's")

    @field_validator("tx", "rx")
    @classmethod
    def _finite(cls, v):
        if v is not None and not np.all(np.isfinite(v)):
            raise InputError("antenna position must be finite")
        if v is not None and np.max(np.abs(v)) > MAX_COORDINATE_M:
            raise InputError(f"antenna position {tuple(v)} is more than {MAX_COORDINATE_M:g} m from the origin "
                             "in some coordinate (a room-scale simulator; check the units: metres)")
        return v

    @property
    def tx_pos(self) -> np.ndarray:
        return np.asarray(self.tx, dtype=float)

    @property
    def rx_pos(self) -> np.ndarray:
        return np.asarray(self.tx if self.rx is None else self.rx, dtype=float)

    @property
    def monostatic(self) -> bool:
        return float(np.linalg.norm(self.tx_pos - self.rx_pos)) < MONOSTATIC_TOLERANCE_M


# The Glasgow dataset's radar (Ancortek SDR-KIT 580AD; README of ../shared/realdata): 5.8 GHz, 400 MHz sweep,
# 1 ms chirp = PRI (PRF 1 kHz), 128 complex samples per chirp (fs 128 kHz: bins of c/2B = 0.375 m, beat
# frequencies up to 48 m). max_range_m only bounds the ranges the waveform must resolve (validation).
GLASGOW_WAVEFORM = Waveform(carrier_hz=5.8e9, bandwidth_hz=400e6, pri_s=1e-3, samples_per_chirp=128,
                            max_range_m=24.0)
# Elevation half-power beamwidth of the 580AD kit's Yagis [deg]: no data sheet was found; commercial
# 5.8 GHz Yagis of 12-17 dBi state 18-45 deg in the E/H planes, so a deployment-randomised plan draws from
# this range (the default 24 deg makes the model's directivity the 17 dBi quoted for the kit).
GLASGOW_HPBW_EL_RANGE_DEG = (18.0, 45.0)
# Height of the radar above the floor and horizontal distance to the person [m]. The dataset states
# "1-4 m" for the person; the antenna height is not documented, a tripod gives 0.5-2 m.
GLASGOW_DISTANCE_RANGE_M = (1.0, 4.0)
GLASGOW_HEIGHT_RANGE_M = (0.5, 2.0)
# Range band summed into p(v,t) for simulated scenes. The Glasgow script sums range bins 10..30 (3.75-11.25 m
# as labelled), 21 bins, while the README puts people 1-4 m away: the hardware adds an undocumented offset
# (see DSPConfig.glasgow). A simulation has no offset, so the band is moved to where the body is, keeping the
# script's 21 bins: with the magnitude range sum every summed bin adds its noise, so the bin count (not the
# position) sets the noise floor under the signature. Bins 2..22 = 0.75-8.25 m hold a person 1-4 m away and
# a walk of +-2 m about 4 m, and skip bins 0-1 (antenna coupling, DC).
GLASGOW_SIM_BAND_M = (0.75, 8.25)


def glasgow_dsp() -> DSPConfig:
    """The Glasgow dataset's DSP (`DSPConfig.glasgow`) with the range band at the body (GLASGOW_SIM_BAND_M)."""
    return GLASGOW_DSP.model_copy(update={"min_range_m": GLASGOW_SIM_BAND_M[0], "max_range_m": GLASGOW_SIM_BAND_M[1]})


def _seed_links() -> list[Link]:
    return [Link(name="radar1", tx=(3.0, 0.0, 1.1)), Link(name="radar2", tx=(0.0, -3.0, 1.1))]


class RadarConfig(BaseModel):
    """Waveform, DSP settings and links of a (distributed MIMO) radar. Defaults: the seed's 2x2 system."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    waveform: Waveform = Field(default_factory=Waveform)
    dsp: DSPConfig = Field(default_factory=DSPConfig)
    links: list[Link] = Field(default_factory=_seed_links, min_length=1)
    antenna: AntennaPattern = Field(default_factory=lambda: ANCORTEK_2400T2R4.antenna,
                                    description="antenna pattern of links without their own")
    receiver: ReceiverConfig | None = Field(default_factory=lambda: ANCORTEK_2400T2R4.receiver,
                                            description="transmit power and receiver noise; None: noiseless")
    orientation_deg: float = Field(0.0, allow_inf_nan=False, ge=-1e6, le=1e6,
                                   description="rotation [deg] about z applied to the links as given (the seed's "
                                   "direction angle); kept for provenance")

    def __repr__(self) -> str:
        def where(lk):
            rx = "" if lk.rx is None else f" -> {tuple(round(x, 2) for x in lk.rx)}"
            return f"{lk.name} {tuple(round(x, 2) for x in lk.tx)}{rx}"

        shown = "; ".join(where(lk) for lk in self.links[:3])
        shown += f"; ... {len(self.links) - 3} more" if len(self.links) > 3 else ""
        rx = "noiseless" if self.receiver is None else (f"receiver {self.receiver.transmit_power_dbm:g} dBm, NF "
                                                        f"{self.receiver.noise_figure_db:g} dB")
        n = len(self.links)
        text = (f"<Radar: {n} link{'s' if n != 1 else ''} (m: {shown}), turned {self.orientation_deg:g} deg; "
                f"{self.waveform!r}; DSP window {self.dsp.window_chirps} hop {self.dsp.hop_chirps} chirps, "
                f"{self.dsp.range_sum} range sum, {self.dsp.static_removal} MTI; {self.antenna.kind} antennas; {rx}>")
        return text if len(text) <= 600 else text[:595] + "...>"

    @model_validator(mode="after")
    def _unique_names(self) -> "RadarConfig":
        names = [link.name for link in self.links]
        if len(set(names)) != len(names):
            raise InputError(f"link names must be unique, got {names}")
        return self

    @classmethod
    def seed(cls, direction: int = 1, **overrides) -> "RadarConfig":
        """The seed's 2x2 distributed MIMO radar (two monostatic Ancortek radars, 24.125 GHz) turned for one of
        the seed's directions.

        Args:
            direction: the seed's direction 1..18 (Radar 1 at 20 (k - 1) degrees).
            **overrides: RadarConfig fields to replace (e.g. ``waveform=Waveform(...)``, ``receiver=None``).
        """
        return cls(**overrides).for_direction(direction)

    @classmethod
    def monostatic(cls, position, name: str = "radar1", **overrides) -> "RadarConfig":
        """One monostatic radar at `position` [3] (m), seed waveform and DSP unless overridden.

        Args:
            position: antenna position (x, y, z) [m].
            name: the link's name.
            **overrides: RadarConfig fields to replace (waveform, dsp, receiver, ...).
        """
        return cls(links=[Link(name=name, tx=tuple(float(x) for x in position))], **overrides)

    @classmethod
    def glasgow(cls, height_m: float = 1.0, distance_m: float = 2.5, downtilt_deg: float = 0.0,
                hpbw_el_deg: float | None = None, **overrides) -> "RadarConfig":
        """The Glasgow dataset's radar: one monostatic Ancortek SDR-KIT 580AD link ``radar1`` at
        (`distance_m`, 0, `height_m`) (m) facing a person at the origin (procedural motions face +x, so they
        face it), Yagi antennas (`ANCORTEK_580AD`) with a horizontal boresight toward the person's vertical
        axis, the 580AD receiver, GLASGOW_WAVEFORM (5.8 GHz, 400 MHz, 1 ms chirp, 128 samples) and the
        Glasgow DSP on the body's range band (`glasgow_dsp`: velocity axis cropped to +-6 m/s as the images).

        Args:
            height_m: antenna height above the floor [m], 0.5..2.0 (a tripod; undocumented in the dataset).
            distance_m: horizontal distance radar - person [m], 1.0..4.0 (the dataset's "1-4 m").
            downtilt_deg: beam tilt below horizontal [deg] (negative: up), -60..60; how the kit was aimed is
                not published.
            hpbw_el_deg: the Yagis' elevation half-power beamwidth [deg] (default 24, `ANCORTEK_580AD`);
                `GLASGOW_HPBW_EL_RANGE_DEG` is the honest range (no data sheet of the kit's antennas).
            overrides: other RadarConfig fields (e.g. ``receiver=None`` for noiseless IQ).

        Raises:
            rtchannel.errors.ConfigError: a height or distance outside its range (one line).
        """
        from rtchannel.errors import ConfigError

        for name, value, (lo, hi) in (("height_m", height_m, GLASGOW_HEIGHT_RANGE_M),
                                      ("distance_m", distance_m, GLASGOW_DISTANCE_RANGE_M)):
            if isinstance(value, bool) or not (isinstance(value, (int, float, np.number)) and np.isfinite(value)
                                               and lo <= value <= hi):
                raise ConfigError(f"Radar.glasgow: {name} must be a number in {lo:g}..{hi:g} m, got {value!r}")
        antenna = ANCORTEK_580AD.antenna.model_copy(update={"look_at": (0.0, 0.0, float(height_m))})
        antenna = type(antenna).model_validate({**antenna.model_dump(), "downtilt_deg": float(downtilt_deg),
                                                **({} if hpbw_el_deg is None else {"hpbw_el_deg": float(hpbw_el_deg)})})
        fields = {"waveform": GLASGOW_WAVEFORM, "dsp": glasgow_dsp(), "antenna": antenna,
                  "receiver": ANCORTEK_580AD.receiver,
                  "links": [Link(name="radar1", tx=(float(distance_m), 0.0, float(height_m)))], **overrides}
        return cls(**fields)

    @classmethod
    def from_file(cls, path: str | Path) -> "RadarConfig":
        """Load a radar from a file; raises pydantic's ValidationError naming a bad field, or
        `rtchannel.errors.ConfigError` (one line naming the file and line) for syntax errors, alias bombs and
        non-mappings (`rtchannel.safe_yaml`).

        Args:
            path: a YAML or JSON file of RadarConfig fields (waveform, dsp, links, antenna, receiver).
        """
        from rtchannel.safe_yaml import read_yaml_mapping

        data = read_yaml_mapping(Path(path), "radar config", max_bytes=1_000_000)  # a radar is a few hundred bytes
        return cls.model_validate(data or {})

    def rotated(self, angle_deg: float) -> "RadarConfig":
        """All antennas (positions and patterns) rotated about the vertical z axis.

        Args:
            angle_deg: rotation [deg], counter-clockwise seen from above.
        """
        a = np.deg2rad(angle_deg)
        rz = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])

        def rot(p):
            return None if p is None else tuple(float(x) for x in rz @ np.asarray(p, dtype=float))

        def turn(ant):
            return None if ant is None else ant.rotated_about_z(angle_deg)

        links = [link.model_copy(update={"tx": rot(link.tx), "rx": rot(link.rx), "tx_antenna": turn(link.tx_antenna),
                                         "rx_antenna": turn(link.rx_antenna)}) for link in self.links]
        return self.model_copy(update={"links": links, "antenna": turn(self.antenna),
                                       "orientation_deg": wrap_deg(self.orientation_deg + angle_deg)})

    def antennas(self, link: Link) -> tuple:
        """(transmit, receive) antenna patterns of a link (its own, else the radar's).

        Args:
            link: one of this radar's `Link`s.
        """
        return (link.tx_antenna or self.antenna, link.rx_antenna or self.antenna)

    def link_gain(self, link: Link, tx_targets: np.ndarray, rx_targets: np.ndarray | None = None) -> np.ndarray:
        """Antenna amplitude factor sqrt(G_tx G_rx) [...] float64 of paths of a link.

        Args:
            link: one of this radar's `Link`s.
            tx_targets: points [..., 3] float (m) the paths leave the transmitter towards.
            rx_targets: points [..., 3] float (m) the paths reach the receiver from (default `tx_targets`).
        """
        from processing.radar.antenna import link_gain

        tx_ant, rx_ant = self.antennas(link)
        if tx_ant.kind == "isotropic" and rx_ant.kind == "isotropic":
            return np.ones(np.shape(tx_targets)[:-1])
        return link_gain(tx_ant, link.tx_pos, rx_ant, link.rx_pos, tx_targets, rx_targets)

    def for_direction(self, direction: int) -> "RadarConfig":
        """The radar set rotated for one of the seed's directions.

        Args:
            direction: 1..18 (Radar 1 at 20 (k - 1) degrees).
        """
        return self.rotated(direction_angles(direction)[0])


def wrap_deg(angle: float) -> float:
    """Angle wrapped into [-180, 180) degrees."""
    return float((angle + 180.0) % 360.0 - 180.0)


def direction_angles(direction: int) -> tuple[float, float]:
    """(theta_R1, theta_R2) in degrees of the seed's direction k = 1..18; theta_R1 - theta_R2 = 90 deg.

    Direction 11 gives (-160, 110), as in the seed's Fig. 6.
    """
    if not (isinstance(direction, (int, np.integer)) and 1 <= direction <= 18):
        raise InputError(f"direction must be an integer 1..18, got {direction!r}")
    t1 = wrap_deg(20.0 * (direction - 1))
    return t1, wrap_deg(t1 - 90.0)


Radar = RadarConfig  # the public name (`from rtchannel import Radar`)
