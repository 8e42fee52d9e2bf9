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
the software's sawtooth with no idle time), so recordings go through `processing.dsp.signatures.signatures`
exactly like simulated IQ. The simulator's IQ convention is kept as written; `conjugate=True` flips the
sign of Doppler for recordings made with the opposite I/Q convention (some vendor readers conjugate).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from processing.atomic import atomic_path
from processing.errors import InputError
from processing.radar.waveform import Waveform

_SPACE = re.compile(r"\s+")
# Limits (docs/validation.md), each with its reason:
CARRIER_RANGE_HZ = (1e8, 3e11)  # FMCW kits: 5.8, 9.7, 24, 25, 77 GHz; outside 0.1-300 GHz is a corrupt header
SWEEP_RANGE_S = (1e-6, 1.0)  # chirp repetition: microseconds to a second
SAMPLES_RANGE = (2, 65536)  # samples per sweep (the kits write 64..1024)
BANDWIDTH_RANGE_HZ = (1e5, 1e11)  # 0.1 MHz .. 100 GHz sweep
MAX_ABS_SAMPLE = 1e12  # |re|, |im|: ADC values are < 1e6; this keeps |FFT|^2 of 4096-sample chirps finite in float32
MAX_DAT_BYTES = 4 << 30  # ~130 M samples (~17 min of 128-sample 1-ms sweeps); the IQ needs ~0.27x the text
MAX_CHANNELS = 8
_BLOCK = 65536  # samples parsed per block (bounded transient memory: ~2 MB of Python objects)
_STRIP = str.maketrans({" ": None, "\t": None, "\r": None, "\n": None, "\f": None, "\v": None})


class AncortekFormatError(InputError):
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
    s = text.translate(_STRIP)
    if s[-1:] in ("i", "I", "J"):  # the vendor's imaginary unit (only as the last character: "inf" stays)
        s = s[:-1] + "j"
    try:
        return complex(s)
    except ValueError:
        raise AncortekFormatError(f"{path}: line {line_no}: not a complex sample: {text.strip()[:40]!r}") from None


def _count_lines(path: Path) -> int:
    """Upper bound on the text lines of `path` (CRLF, LF or CR line ends), read in 4 MB chunks."""
    lf = cr = 0
    with open(path, "rb") as f:
        while chunk := f.read(1 << 22):
            lf += chunk.count(b"\n")
            cr += chunk.count(b"\r")
    return max(lf, cr) + 1


def _check_block(path: Path, block: np.ndarray, lines: np.ndarray) -> None:
    """AncortekFormatError naming the first line whose sample is non-finite or beyond MAX_ABS_SAMPLE."""
    with np.errstate(invalid="ignore"):
        bad = ~((np.abs(block.real) <= MAX_ABS_SAMPLE) & (np.abs(block.imag) <= MAX_ABS_SAMPLE))
    if bad.any():
        k = int(np.argmax(bad))
        raise AncortekFormatError(f"{path}: line {int(lines[k])}: sample {block[k]} is not finite or beyond "
                                  f"+-{MAX_ABS_SAMPLE:g} (corrupted data)")


def _read_samples(path: Path, f, first_line: int, capacity: int) -> np.ndarray:
    """Samples after the header as complex64 [n], parsed block by block from the open text file `f`
    (memory: the output plus one block; no Python object per sample is kept)."""
    out = np.empty(max(capacity, 0), np.complex64)
    n = 0
    vals: list[complex] = []
    nums: list[int] = []
    for no, ln in enumerate(f, first_line):
        if ln.isspace() or not ln:
            continue
        vals.append(_parse_complex(ln, path, no))
        nums.append(no)
        if len(vals) == _BLOCK:
            n = _flush(path, out, n, vals, nums)
    return out[:_flush(path, out, n, vals, nums)]


def _flush(path: Path, out: np.ndarray, n: int, vals: list, nums: list) -> int:
    if vals:
        block = np.array(vals, np.complex128)
        _check_block(path, block, np.asarray(nums))
        if n + len(vals) > out.size:  # mixed line ends beat the estimate: grow (never happens with CRLF/LF)
            out.resize(max(2 * out.size, n + len(vals)), refcheck=False)
        out[n:n + len(vals)] = block
        n += len(vals)
        vals.clear()
        nums.clear()
    return n


def _in(value: float, lo: float, hi: float) -> bool:
    return lo <= value <= hi  # False for nan


def read_dat(path: str | Path, n_channels: int = 1, conjugate: bool = False, allow_partial: bool = False,
             max_range_m: float = 10.0) -> Recording:
    """Read an Ancortek `.dat` recording.

    Streams the file: peak memory is about the complex64 IQ (~0.27x the text) plus a 65536-sample block.

    Args:
        path: the text file.
        n_channels: interleaved receive channels in the file (1 or 2 for the common kits; at most 8).
        conjugate: conjugate the samples (opposite I/Q convention).
        allow_partial: drop an incomplete last sweep instead of raising.
        max_range_m: the `Waveform.max_range_m` to attach (clipped to the unambiguous range) [m].

    Raises:
        AncortekFormatError: unreadable file, missing/invalid header, malformed, non-finite or absurd
            sample (message names file and line), or (unless `allow_partial`) a sample count that is not
            a whole number of sweeps.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"recording not found: {path}")
    if (isinstance(n_channels, bool) or not isinstance(n_channels, (int, np.integer))
            or not 1 <= n_channels <= MAX_CHANNELS):
        raise AncortekFormatError(f"{path}: n_channels must be an integer 1..{MAX_CHANNELS}, got {n_channels!r}")
    if not (isinstance(max_range_m, (int, float)) and max_range_m > 0 and np.isfinite(max_range_m)):
        raise AncortekFormatError(f"{path}: max_range_m must be a positive finite distance, got {max_range_m!r}")
    try:
        size = path.stat().st_size
        if size > MAX_DAT_BYTES:
            raise AncortekFormatError(f"{path}: file of {size / 2**30:.1f} GiB exceeds the {MAX_DAT_BYTES >> 30} GiB "
                                      "limit")
        capacity = _count_lines(path)
        with open(path, encoding="ascii", errors="replace", newline=None) as f:
            head, no = [], 0
            for no, ln in enumerate(f, 1):
                if ln.strip():
                    head.append((no, ln))
                    if len(head) == 4:
                        break
            if len(head) < 4:
                raise AncortekFormatError(f"{path}: header needs 4 lines (carrier, sweep time, samples per sweep, "
                                          f"bandwidth), found {len(head)}")
            values = []
            for (hno, text), what in zip(head, ("carrier frequency", "sweep time", "samples per sweep", "bandwidth")):
                try:
                    values.append(float(_SPACE.sub("", text)))
                except ValueError:
                    raise AncortekFormatError(f"{path}: line {hno}: {what} is not a number: "
                                              f"{text.strip()[:40]!r}") from None
            fc, sweep_ms, n_samp, bw = values
            fc_hz = fc * 1e9 if fc < 1e3 else fc
            bw_hz = bw * 1e6 if bw < 1e5 else bw
            pri = sweep_ms * 1e-3
            checks = ((fc_hz, CARRIER_RANGE_HZ, "carrier frequency [Hz]", 1), (pri, SWEEP_RANGE_S, "sweep time [s]", 2),
                      (n_samp, SAMPLES_RANGE, "samples per sweep", 3), (bw_hz, BANDWIDTH_RANGE_HZ, "bandwidth [Hz]", 4))
            for value, (lo, hi), what, k in checks:
                if not _in(value, lo, hi) or (k == 3 and not float(n_samp).is_integer()):
                    raise AncortekFormatError(f"{path}: line {head[k - 1][0]}: implausible header: {what} {value:g} "
                                              f"(need {'an integer ' if k == 3 else ''}{lo:g}..{hi:g})")
            samples = _read_samples(path, f, no + 1, capacity - no)
    except OSError as exc:
        raise AncortekFormatError(f"{path}: cannot read file: {exc.strerror or exc}") from None
    n = int(n_samp)
    per_sweep = n * n_channels
    n_sweeps, rest = divmod(samples.size, per_sweep)
    if rest and not allow_partial:
        raise AncortekFormatError(f"{path}: truncated: {samples.size} samples is not a whole number of sweeps "
                                  f"({n} samples x {n_channels} channel(s) per sweep)")
    if n_sweeps == 0:
        raise AncortekFormatError(f"{path}: no complete sweep ({samples.size} samples, {per_sweep} per sweep)")
    samples = samples[:n_sweeps * per_sweep]
    if conjugate:
        np.conjugate(samples, out=samples)
    iq = [np.ascontiguousarray(samples[c::n_channels].reshape(n_sweeps, n)) for c in range(n_channels)]
    try:
        probe = Waveform(carrier_hz=fc_hz, bandwidth_hz=bw_hz, pri_s=pri, samples_per_chirp=n, max_range_m=1e-3)
    except ValueError as e:  # pydantic's ValidationError is a ValueError
        raise AncortekFormatError(f"{path}: header does not describe a valid FMCW waveform: "
                                  f"{str(e).splitlines()[-2].strip() if len(str(e).splitlines()) > 1 else e}") from None
    wf = Waveform(**{**probe.model_dump(), "max_range_m": min(max_range_m, 0.999 * probe.max_unambiguous_range)})
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
        raise InputError("every channel must be an [n_chirps, n_samples] array of the same shape")
    if chans[0].shape[1] != wf.samples_per_chirp:
        raise InputError(f"IQ has {chans[0].shape[1]} samples per chirp, waveform says {wf.samples_per_chirp}")
    if abs(wf.chirp_s - wf.pri_s) > 1e-12 * wf.pri_s:
        raise InputError("the .dat format has no idle time: chirp duration must equal the PRI")
    flat = np.stack([a.reshape(-1) for a in chans], axis=1).reshape(-1)
    fmt = f"%.{digits - 1}e"
    re_s = np.char.mod(fmt, flat.real.astype(np.float64))
    im_s = np.char.mod("%+." + str(digits - 1) + "e", flat.imag.astype(np.float64))
    body = np.char.add(np.char.add(re_s, im_s), "i")
    path = Path(path)
    head = [repr(wf.carrier_hz / 1e9), repr(wf.pri_s * 1e3), str(wf.samples_per_chirp), repr(wf.bandwidth_hz / 1e6)]
    with atomic_path(path) as tmp, open(tmp, "w") as f:
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
    """Signatures of recordings, one sample per activity: [(name, {link: {"p_vt", "velocity", "time", "valid",
    "power"}})].

    One file per sample when it holds one interleaved channel per link (`n_channels == len(links)`, channel
    i -> links[i]); otherwise one single-channel file per link, paired by name: ``walk01_radar1.dat`` and
    ``walk01_radar2.dat`` form sample ``walk01``. A single-link model takes each file's first channel.

    `dsp` is the `DSPConfig` (or its JSON dict, as stored in dataset entries and classifier checkpoints)
    that the simulated data being compared with went through; default `DSPConfig()`. Each recording's own
    header gives the waveform, so the same DSP settings give the same physical axes.
    """
    from processing.dsp.signatures import DSPConfig, signatures

    dsp = DSPConfig.model_validate(dsp) if isinstance(dsp, dict) else (dsp or DSPConfig())
    links = list(links)

    def sig_dict(iq, wf):
        s = signatures(iq, wf, dsp)
        # valid and power as a simulated sample carries them: the classifier's preprocessing uses both
        return {"p_vt": s.p_vt, "velocity": s.velocity, "time": s.time, "valid": s.valid, "power": s.power}

    paths = sorted(Path(p) for p in paths)
    out: list[tuple[str, dict]] = []
    if n_channels == len(links) or len(links) == 1:
        for p in paths:
            rec = read_dat(p, n_channels=n_channels, conjugate=conjugate, allow_partial=allow_partial)
            out.append((p.stem, {ln: sig_dict(rec.iq[i], rec.waveform) for i, ln in enumerate(links)}))
        return out
    if n_channels != 1:
        raise InputError(f"files hold {n_channels} channels but the model needs {len(links)} links")
    samples: dict[str, dict] = {}
    for p in paths:
        hit = [ln for ln in links if ln.lower() in p.stem.lower()]
        if len(hit) != 1:
            raise InputError(f"{p.name}: cannot tell which link it is; name files like NAME_{links[0]}.dat")
        key = re.sub(re.escape(hit[0]), "", p.stem, flags=re.IGNORECASE).strip("_- .")
        rec = read_dat(p, conjugate=conjugate, allow_partial=allow_partial)
        samples.setdefault(key, {})[hit[0]] = sig_dict(rec.iq[0], rec.waveform)
    for key, s in samples.items():
        if len(s) != len(links):
            missing = sorted(set(links) - set(s))
            raise InputError(f"recording {key!r} has no file for link {missing[0]!r}")
    return sorted(samples.items())
