"""What a simulation returns, as nouns: the channel (`PathSets`) and the result (`SimulationResult`).

Each prints a short summary, saves and loads as a pair returning the same type (`PathSets.save/load`: HDF5,
bit-identical, with the radar and the parameters that traced it; `SimulationResult.save/load`:
`signature.h5`), exposes labelled arrays (`to_xarray`) and plots onto an ``ax=`` the caller gives, returning
the figure; writing figures is a separate step (`SimulationResult.save_figures`).
"""
from __future__ import annotations

import json
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from processing.dsp.signatures import Signature
from processing.pathset import PathSet
from rtchannel.radar import RadarConfig


def _json_normal(value):
    """`value` as it reads back from JSON (tuples as lists, objects by their str), for comparing configs."""
    return json.loads(json.dumps(value, sort_keys=True, default=str))


def _seconds(timing: dict) -> str:
    return ", ".join(f"{k} {v:.3g} s" for k, v in timing.items()) or "not timed"


def _names(names, most: int = 4) -> str:
    names = list(names)
    return ", ".join(names[:most]) + (f", ... ({len(names) - most} more)" if len(names) > most else "")


@dataclass
class LinkResult:
    """One link's result.

    Attributes:
        signature: the link's `Signature` (p(v,t), mean velocity, range distribution, ...).
        chirp_times: start time of every chirp [n_chirps] float64 (s).
        iq: raw IQ [n_chirps, n_samples] complex64 when kept (`keep_iq`), else None.
    """

    signature: Signature
    chirp_times: np.ndarray
    iq: np.ndarray | None = None

    def __repr__(self) -> str:
        iq = ("no IQ" if self.iq is None
              else f"IQ [{' x '.join(map(str, np.shape(self.iq)))}] {np.asarray(self.iq).dtype}")
        return f"<LinkResult: {np.size(self.chirp_times)} chirps, {iq}; {self.signature!r}>"

    def __eq__(self, other) -> bool:
        if not isinstance(other, LinkResult):
            return NotImplemented
        same_iq = (self.iq is None and other.iq is None) or (
            self.iq is not None and other.iq is not None and np.shape(self.iq) == np.shape(other.iq)
            and np.array_equal(self.iq, other.iq))
        return self.signature == other.signature and same_iq and np.array_equal(self.chirp_times, other.chirp_times)

    # not hashable (mutable arrays): @dataclass with eq=True and frozen=False sets __hash__ = None


@dataclass
class SimulationResult:
    """Per-link results, the wall-clock split [s] between backend, synthesis and DSP, and every
    parameter that produced them (`config`, JSON-serialisable; stored by `save`)."""

    links: dict[str, LinkResult]
    timing: dict[str, float] = field(default_factory=dict)
    config: dict = field(default_factory=dict)

    @property
    def signatures(self) -> dict[str, Signature]:
        """{link name: Signature} (p(v,t), mean velocity, range distribution, ...)."""
        return {name: r.signature for name, r in self.links.items()}

    @property
    def iq(self) -> dict[str, np.ndarray]:
        """{link name: raw IQ [chirps, samples] complex64} of the links whose IQ was kept (`keep_iq`)."""
        return {name: r.iq for name, r in self.links.items() if r.iq is not None}

    def __repr__(self) -> str:
        c = self.config
        what = f"{c.get('activity') or 'simulation'!r} via {c.get('backend') or '?'}"
        first = next(iter(self.links.values()), None)
        if first is None:
            return f"<SimulationResult {what}: no links>"
        s = first.signature
        t = np.asarray(s.time)
        span = f"{t[0]:.3g}..{t[-1]:.3g} s" if t.size else "no windows"
        iq = f"IQ kept for {len(self.iq)}" if self.iq else "no IQ kept"
        return (f"<SimulationResult {what}: {len(self.links)} links ({_names(self.links)}); p(v,t) "
                f"[{np.size(s.velocity)} velocity x {t.size} time] over {span}, |v| < {s.v_max:.3g} m/s; {iq}; "
                f"timing {_seconds(self.timing)}>")

    def __eq__(self, other) -> bool:
        """Equal links (every array), timing and config (as JSON, the form `save` stores)."""
        if not isinstance(other, SimulationResult):
            return NotImplemented
        return (self.links == other.links and self.timing == other.timing
                and _json_normal(self.config) == _json_normal(other.config))

    # not hashable (mutable arrays): @dataclass with eq=True and frozen=False sets __hash__ = None

    def save(self, path: str | Path, seed: int | None = None) -> Path:
        """Write `signature.h5` (DESIGN.md layout, atomically) with the parameters that made it, the chirp
        times and the timing; the raw IQ is stored for links that kept it. `SimulationResult.load` reads it
        back equal.

        Args:
            path: the file to write.
            seed: the root attribute ``seed`` (default: the motion's seed).

        Returns:
            `path`.
        """
        from processing.io.signature_file import write_signature_file

        cfg = self.config
        radar = cfg.get("radar", {})
        links = {lk["name"]: lk for lk in radar.get("links", [])}
        link_attrs = {n: {"tx": np.asarray(lk["tx"], float),
                          "rx": np.asarray(lk["tx"] if lk.get("rx") is None else lk["rx"], float)}
                      for n, lk in links.items()}
        motion = cfg.get("motion", {})
        return write_signature_file(
            path, self.signatures, activity=cfg.get("activity", ""), backend=cfg.get("backend", ""),
            seed=int(motion.get("seed", 0) if seed is None else seed),
            direction_deg=float(radar.get("orientation_deg", 0.0)), config=cfg, link_attrs=link_attrs,
            iq=self.iq or None, chirp_times={n: r.chirp_times for n, r in self.links.items()}, timing=self.timing)

    @classmethod
    def load(cls, path: str | Path) -> "SimulationResult":
        """The result `save` wrote to `path` (equal to it: signatures, chirp times, kept IQ, timing, config).
        Files written before chirp times were stored give empty `chirp_times`.

        Args:
            path: a `signature.h5`.
        """
        from processing.io.signature_file import read_signature_parts

        parts = read_signature_parts(path)
        links = {name: LinkResult(signature=sig, chirp_times=parts["chirp_times"].get(name, np.zeros(0)),
                                  iq=parts["iq"].get(name)) for name, sig in parts["signatures"].items()}
        attrs = parts["attrs"]
        return cls(links=links, timing=attrs.get("timing", {}), config=attrs["config"])

    def to_xarray(self):
        """The signatures of every link as one `xarray.Dataset` with a ``link`` dimension (the links of one
        radar share their axes: velocity [m/s], time [s], range [m]); ``config`` as a JSON attribute."""
        import xarray as xr

        names = list(self.links)
        ds = xr.concat([self.links[n].signature.to_xarray() for n in names], dim="link", join="exact",
                       combine_attrs="override")
        return ds.assign_coords(link=names).assign_attrs(config=json.dumps(self.config, sort_keys=True, default=str))

    def plot(self, ax=None, kind: str = "pvt", title: str | None = None):
        """One figure of every link: ``kind`` "pvt" (micro-Doppler p(v,t) with the mean velocity),
        "mean_velocity", "range" (range-time map) or "range_doppler", drawn onto `ax` (one Axes per link;
        "mean_velocity" one in all) or a new figure. Returns the `Figure`; write it with
        `processing.plots.signatures.save_figure`, or write the whole set with `save_figures`.

        The old call ``plot(out_dir, title=...)`` (a folder in place of ``ax``) still writes the PNGs and
        returns their paths, with a DeprecationWarning, for one release.

        Args:
            ax: matplotlib Axes to draw on (default: a new figure).
            kind: which figure.
            title: figure title (default: activity, backend and radar orientation).
        """
        import os

        from processing.errors import InputError
        from processing.plots import signatures as plots

        if isinstance(ax, (str, os.PathLike)):
            warnings.warn("SimulationResult.plot(out_dir) is deprecated: use save_figures(out_dir) to write the "
                          "PNGs, plot(ax=...) to draw", DeprecationWarning, stacklevel=2)
            return self.save_figures(Path(ax), title=title)
        draw: dict[str, Callable[..., Any]]
        draw = {"pvt": plots.plot_pvt, "mean_velocity": plots.plot_mean_velocity, "range": plots.plot_range,
                "range_doppler": plots.plot_range_doppler}
        if kind not in draw:
            raise InputError(f"plot kind must be one of {', '.join(draw)}, got {kind!r}")
        return draw[kind](self.signatures, ax=ax, title=self._title() if title is None else title)

    def save_figures(self, out_dir: str | Path, title: str | None = None) -> list[Path]:
        """PNG figures (p(v,t), mean velocity, range-time, range-Doppler) into `out_dir`; returns their paths.

        Args:
            out_dir: folder to write into (created if missing).
            title: figure title (default: activity, backend and radar orientation).
        """
        from processing.plots.signatures import save_figures

        return save_figures(self.signatures, Path(out_dir), title=self._title() if title is None else title)

    def _title(self) -> str:
        c = self.config
        return f"{c.get('activity', '')} ({c.get('backend', '')}, {c.get('radar', {}).get('orientation_deg', 0):g} deg)"


@dataclass
class PathSets:
    """The channel between motion and radar: one `PathSet` per link (delays [s], complex gains with
    |a|^2 = P_r/P_t, path ids, delay rates [s/s] at frame times [s]), the radar whose links they belong to,
    and what made them (`config`: motion, backend, options; `timing` [s]). `trace` makes it, `synthesise`
    turns it into raw IQ and signatures, so a channel can be stored (`save`/`load`), inspected or
    synthesised for several waveforms and DSP settings of the same antennas."""

    paths: dict[str, PathSet]
    radar: RadarConfig
    config: dict = field(default_factory=dict)
    timing: dict[str, float] = field(default_factory=dict)

    def __getitem__(self, link: str) -> PathSet:
        return self.paths[link]

    def __iter__(self):
        return iter(self.paths)

    def __len__(self) -> int:
        return len(self.paths)

    def __repr__(self) -> str:
        c = self.config
        what = f"{c.get('activity') or 'motion'!r} via {c.get('backend') or '?'}"
        first = next(iter(self.paths.values()), None)
        if first is None:
            return f"<PathSets {what}: no links>"
        t = first.times
        n_paths = sum(ps.n_paths for ps in self.paths.values())
        return (f"<PathSets {what}: {len(self.paths)} links ({_names(self.paths)}); {first.n_frames} frames over "
                f"{t[-1] - t[0]:.3g} s; {n_paths} paths in all (delays [s], gains |a|^2 = P_r/P_t); carrier "
                f"{self.radar.waveform.carrier_hz / 1e9:.4g} GHz; timing {_seconds(self.timing)}>")

    def __eq__(self, other) -> bool:
        """Bit-identical path sets, the same radar, config and timing (as JSON, the form `save` stores)."""
        if not isinstance(other, PathSets):
            return NotImplemented
        return (self.paths == other.paths and self.radar == other.radar and self.timing == other.timing
                and _json_normal(self.config) == _json_normal(other.config))

    # not hashable (mutable arrays): @dataclass with eq=True and frozen=False sets __hash__ = None

    def save(self, path: str | Path) -> Path:
        """Write the channel to the HDF5 file `path` (atomically): every link's arrays bit for bit, the radar
        (JSON), the parameters that traced it (`config`) and the timing. `PathSets.load` reads it back equal.

        Args:
            path: the file to write (e.g. ``channel.h5``).

        Returns:
            `path`.
        """
        from processing.io.pathset_file import write_pathsets

        return write_pathsets(path, self.paths, {"radar": self.radar.model_dump_json(), "config": self.config,
                                                 "timing": self.timing})

    @classmethod
    def load(cls, path: str | Path) -> "PathSets":
        """The channel `save` wrote to `path`.

        Args:
            path: a channel file.
        """
        from processing.io.pathset_file import read_pathsets

        attrs, paths = read_pathsets(path, json_attrs=("config", "timing"))
        return cls(paths=paths, radar=RadarConfig.model_validate_json(attrs["radar"]), config=attrs["config"],
                   timing=attrs["timing"])

    def to_xarray(self, link: str):
        """One link's paths as an `xarray.Dataset` (`PathSet.to_xarray`: delay [s], gain over time [s], path).

        Args:
            link: the link name.
        """
        return self.paths[link].to_xarray()


def load_signatures(path: str | Path):
    """Deprecated: use `SimulationResult.load(path)`. Returns (root attributes with `config` parsed, {link
    name: Signature}) as before, with a DeprecationWarning (kept for one release).

    Args:
        path: a `signature.h5`.
    """
    from processing.io.signature_file import read_signature_file

    warnings.warn("rtchannel.load_signatures is deprecated: use rtchannel.SimulationResult.load(path)",
                  DeprecationWarning, stacklevel=2)
    return read_signature_file(path)


__all__ = ["LinkResult", "PathSets", "SimulationResult", "load_signatures"]
