"""Raw FMCW recordings in the Ancortek `.dat` text format (SDR-KIT 580AD/2400AD/2400T2R4 software).

Layout, as in the public "Radar signatures of human activities" dataset (University of Glasgow) and the
vendor's MATLAB readers: a plain-text file, one number per line.

    line 1  carrier (centre) frequency   GHz (Hz also accepted: values >= 1e3 are taken as Hz)
    line 2  sweep (chirp) time            ms
    line 3  samples per sweep             integer
    line 4  bandwidth                     MHz (Hz also accepted: values >= 1e5 are taken as Hz)
    line 5+ complex samples, sweep after sweep, e.g. ``-0.0123+0.0456i`` (``i`` or ``j``, spaces
            anywhere, a bare real number allowed). With several receive channels the samples are
            interleaved one by one (channel 1, channel 2, channel 1, ...), as the 2-channel kits write them.

The reader returns IQ [n_chirps, n_samples] per channel and the matching `Waveform` (PRI = sweep time,
the software's sawtooth with no idle time), so recordings go through `processing.dsp.signatures`
exactly like simulated IQ. The simulator's IQ convention is kept as written; `conjugate=True` flips the
sign of Doppler for recordings made with the opposite I/Q convention (some vendor readers conjugate).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from processing.waveform import Waveform

_SPACE = re.compile(r"\s+")


class AncortekFormatError(ValueError):
    """A `.dat` file that is truncated or malformed; the message names the file and line."""


@dataclass
class Recording:
    """One `.dat` recording: IQ per receive channel and the waveform from its header."""

    path: Path
    waveform: Waveform
    iq: list[np.ndarray]  # per channel, complex64 [n_chirps, n_samples]
    header: dict = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        """Recording length [s]."""
        return self.iq[0].shape[0] * self.waveform.pri_s if self.iq else 0.0


def _parse_complex(text: str, path: Path, line_no: int) -> complex:
    s = _SPACE.sub("", text).replace("i", "j").replace("I", "j").replace("J", "j")
    try:
        return complex(s)
    except ValueError:
        raise AncortekFormatError(f"{path}: line {line_no}: not a complex sample: {text.strip()[:40]!r}") from None


def read_dat(path: str | Path, n_channels: int = 1, conjugate: bool = False, allow_partial: bool = False,
             max_range_m: float = 10.0) -> Recording:
    """Read an Ancortek `.dat` recording.

    Args:
        path: the text file.
        n_channels: interleaved receive channels in the file (1 or 2 for the common kits).
        conjugate: conjugate the samples (opposite I/Q convention).
        allow_partial: drop an incomplete last sweep instead of raising.
        max_range_m: the `Waveform.max_range_m` to attach (clipped to the unambiguous range) [m].

    Raises:
        AncortekFormatError: missing/invalid header, malformed sample, or (unless `allow_partial`) a
            sample count that is not a whole number of sweeps.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"recording not found: {path}")
    lines = [(k + 1, ln) for k, ln in enumerate(path.read_text(errors="replace").splitlines()) if ln.strip()]
    if len(lines) < 4:
        raise AncortekFormatError(f"{path}: header needs 4 lines (carrier, sweep time, samples per sweep, "
                                  f"bandwidth), found {len(lines)}")
    head = []
    for (no, text), what in zip(lines[:4], ("carrier frequency", "sweep time", "samples per sweep", "bandwidth")):
        try:
            head.append(float(_SPACE.sub("", text)))
        except ValueError:
            raise AncortekFormatError(f"{path}: line {no}: {what} is not a number: {text.strip()[:40]!r}") from None
    fc, sweep_ms, n_samp, bw = head
    if not (fc > 0 and sweep_ms > 0 and bw > 0 and n_samp >= 1 and float(n_samp).is_integer()):
        raise AncortekFormatError(f"{path}: implausible header {head} (need positive carrier, sweep time, "
                                  "bandwidth and an integer sample count)")
    fc_hz = fc * 1e9 if fc < 1e3 else fc
    bw_hz = bw * 1e6 if bw < 1e5 else bw
    n = int(n_samp)
    samples = np.fromiter((_parse_complex(t, path, no) for no, t in lines[4:]), np.complex128,
                          count=len(lines) - 4)
    per_sweep = n * n_channels
    n_sweeps, rest = divmod(samples.size, per_sweep)
    if rest and not allow_partial:
        raise AncortekFormatError(f"{path}: truncated: {samples.size} samples is not a whole number of sweeps "
                                  f"({n} samples x {n_channels} channel(s) per sweep)")
    if n_sweeps == 0:
        raise AncortekFormatError(f"{path}: no complete sweep ({samples.size} samples, {per_sweep} per sweep)")
    samples = samples[:n_sweeps * per_sweep]
    if conjugate:
        samples = samples.conj()
    iq = [np.ascontiguousarray(samples[c::n_channels].reshape(n_sweeps, n), dtype=np.complex64)
          for c in range(n_channels)]
    pri = sweep_ms * 1e-3
    try:
        probe = Waveform(carrier_hz=fc_hz, bandwidth_hz=bw_hz, pri_s=pri, samples_per_chirp=n, max_range_m=1e-3)
    except ValueError as e:  # pydantic's ValidationError is a ValueError
        raise AncortekFormatError(f"{path}: header does not describe a valid FMCW waveform: "
                                  f"{str(e).splitlines()[-2].strip() if len(str(e).splitlines()) > 1 else e}") from None
    wf = probe.model_copy(update={"max_range_m": min(max_range_m, 0.999 * probe.max_unambiguous_range)})
    header = {"carrier_hz": fc_hz, "sweep_s": pri, "samples_per_sweep": n, "bandwidth_hz": bw_hz,
              "n_channels": n_channels, "n_sweeps": n_sweeps, "dropped_samples": int(rest)}
    return Recording(path=path, waveform=wf, iq=iq, header=header)


def write_dat(path: str | Path, iq, wf: Waveform, digits: int = 9) -> Path:
    """Write IQ [n_chirps, n_samples] (or a list of such arrays, one per channel, interleaved) as `.dat`.

    Header in GHz / ms / samples / MHz; samples as ``a+bi`` with `digits` significant digits (9 keeps
    float32 IQ exact). The chirp duration must equal the PRI (the format has no idle time).
    """
    chans = [np.asarray(a) for a in (iq if isinstance(iq, (list, tuple)) else [iq])]
    if any(a.shape != chans[0].shape or a.ndim != 2 for a in chans):
        raise ValueError("every channel must be an [n_chirps, n_samples] array of the same shape")
    if chans[0].shape[1] != wf.samples_per_chirp:
        raise ValueError(f"IQ has {chans[0].shape[1]} samples per chirp, waveform says {wf.samples_per_chirp}")
    if abs(wf.chirp_s - wf.pri_s) > 1e-12 * wf.pri_s:
        raise ValueError("the .dat format has no idle time: chirp duration must equal the PRI")
    flat = np.stack([a.reshape(-1) for a in chans], axis=1).reshape(-1)
    fmt = f"%.{digits - 1}e"
    re_s = np.char.mod(fmt, flat.real.astype(np.float64))
    im_s = np.char.mod("%+." + str(digits - 1) + "e", flat.imag.astype(np.float64))
    body = np.char.add(np.char.add(re_s, im_s), "i")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    head = [repr(wf.carrier_hz / 1e9), repr(wf.pri_s * 1e3), str(wf.samples_per_chirp), repr(wf.bandwidth_hz / 1e6)]
    with open(path, "w") as f:
        f.write("\n".join(head) + "\n")
        f.write("\n".join(body.tolist()) + "\n")
    return path


# Glasgow "Radar signatures of human activities" file names carry the activity as A01..A06.
GLASGOW_ACTIVITY_CODES = {"A01": "walk", "A02": "sit", "A03": "stand", "A04": "pick", "A05": "drink", "A06": "fall"}
_GLASGOW = re.compile(r"\d+P\d+(A0[1-6])R\d+")  # e.g. 1P36A06R01: person 36, activity 6, repetition 1


def label_from_name(name: str, classes) -> str | None:
    """The activity named in a file name: a class name as a word part (``fall_03.dat``) or a Glasgow code
    (``1P36A06R01.dat`` -> fall). None if there is none or it is not one of `classes`."""
    stem = Path(name).stem.lower()
    parts = re.split(r"[^a-z]+", stem)
    hits = [c for c in classes if c.lower() in parts]
    if len(hits) == 1:
        return hits[0]
    m = _GLASGOW.search(Path(name).stem.upper())
    if m and GLASGOW_ACTIVITY_CODES[m.group(1)] in classes:
        return GLASGOW_ACTIVITY_CODES[m.group(1)]
    return None


def recording_samples(paths, links, dsp=None, n_channels: int = 1, conjugate: bool = False,
                      allow_partial: bool = False) -> list[tuple[str, dict]]:
    """Signatures of recordings, one sample per activity: [(name, {link: {"p_vt", "velocity", "time"}})].

    One file per sample when it holds one interleaved channel per link (`n_channels == len(links)`, channel
    i -> links[i]); otherwise one single-channel file per link, paired by name: ``walk01_radar1.dat`` and
    ``walk01_radar2.dat`` form sample ``walk01``. A single-link model takes each file's first channel.

    `dsp` is the `DSPConfig` (or its JSON dict, as stored in dataset entries and classifier checkpoints)
    that the simulated data being compared with went through; default `DSPConfig()`. Each recording's own
    header gives the waveform, so the same DSP settings give the same physical axes.
    """
    from processing.dsp import DSPConfig, signatures

    dsp = DSPConfig.model_validate(dsp) if isinstance(dsp, dict) else (dsp or DSPConfig())
    links = list(links)

    def sig_dict(iq, wf):
        s = signatures(iq, wf, dsp)
        return {"p_vt": s.p_vt, "velocity": s.velocity, "time": s.time}

    paths = sorted(Path(p) for p in paths)
    out: list[tuple[str, dict]] = []
    if n_channels == len(links) or len(links) == 1:
        for p in paths:
            rec = read_dat(p, n_channels=n_channels, conjugate=conjugate, allow_partial=allow_partial)
            out.append((p.stem, {ln: sig_dict(rec.iq[i], rec.waveform) for i, ln in enumerate(links)}))
        return out
    if n_channels != 1:
        raise ValueError(f"files hold {n_channels} channels but the model needs {len(links)} links")
    samples: dict[str, dict] = {}
    for p in paths:
        hit = [ln for ln in links if ln.lower() in p.stem.lower()]
        if len(hit) != 1:
            raise ValueError(f"{p.name}: cannot tell which link it is; name files like NAME_{links[0]}.dat")
        key = re.sub(re.escape(hit[0]), "", p.stem, flags=re.IGNORECASE).strip("_- .")
        rec = read_dat(p, conjugate=conjugate, allow_partial=allow_partial)
        samples.setdefault(key, {})[hit[0]] = sig_dict(rec.iq[0], rec.waveform)
    for key, s in samples.items():
        if len(s) != len(links):
            missing = sorted(set(links) - set(s))
            raise ValueError(f"recording {key!r} has no file for link {missing[0]!r}")
    return sorted(samples.items())
