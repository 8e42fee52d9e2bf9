"""Accuracy budget: the cheapest backend settings whose signature error stays within a budget.

The error of a setting is the earth-mover distance (Wasserstein-1, m/s) of its p(v,t) from a converged
reference (`rtchannel.analysis.speed_error`), measured per activity by `rtchannel bench --calibrate` for one
radar and written to a calibration table (JSON). Tables for the presets' radars ship with the package
(`rtchannel/calibration/*.json`); a table is chosen by the radar's carrier and range resolution, the two
scales the modelling knobs depend on (the facet size against the wavelength, the range window in bins), so
a user's radar at another carrier or bandwidth needs its own (`rtchannel bench --calibrate --radar FILE`).

Budgets (`--accuracy`). A setting qualifies only when it meets the budget on every calibrated activity
(each against that activity's target), not just on the motion's own: with ~15 candidates and a few seeds
per activity, some setting looks as good as the default on one activity by the speckle draw alone, and on
held-out motions such per-activity picks (e.g. a 5 fps trace rate for a sit-down at 5.8 GHz) missed the
budget (docs/results.md). The record names the motion's activity; its target is the one reported.

- ``exact``: the table's full-accuracy setting (full LOD, every frame traced, every path kept).
- ``balanced``: no worse than today's default setting (the table's ``default`` row), as cheaply as possible:
  a setting's calibrated error exceeds the default's by at most two standard errors of their difference
  (sqrt(sem_default^2 + sem_setting^2), over the calibration's diffuse-phase seeds). One run's speckle moves
  the error by as much as the settings differ, so a smaller excess cannot be told from the speckle draw; it
  is the same test the held-out validation applies (`analysis.accuracy_validation`). The first version
  allowed one standard error of the default alone, which rejected a -30 dB gain cut at 24 GHz for a pick-up
  0.0014 m/s over that line (1.2 standard errors of the difference) while it was better on three activities.
- ``fast``: within `FAST_FACTOR` times the default's error.
- a number: within that many m/s EMD.

When the default itself meets a budget, another setting is chosen only if it is at least `MIN_SAVING`
(10 %) cheaper in the table: calibrated costs are wall times on a shared machine, and a smaller difference
is within their noise.

Rows of role ``measured`` are in the table for the record and never chosen: the gain cuts (-40, -30 dB
relative to the link's strongest path). On the ten calibration motions the -30 dB cut was as good as the
default or better (it drops 12-40 % of each frame's received power, among it the coarse mesh's worst wall
images), but on held-out motions it was far worse on a fall (0.50 against 0.34 m/s) and a 1.4 m/s walk (0.36
against 0.25): a model change whose sign depends on the motion, which no table of a few motions can promise.

The choice (budget, target, chosen row, its calibrated error and cost, the table) goes into every result's
config (`accuracy`) and so into every stored signature. Options the user sets explicitly override the
chosen row's (and are recorded as overrides): the calibrated error then no longer applies to them.
"""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, model_validator

from processing.errors import InputError

BUDGETS = ("fast", "balanced", "exact")
FAST_FACTOR = 1.5  # "fast" allows half again the default's error: between the default and the point model
CALIBRATION_DIR = Path(__file__).resolve().parent / "calibration"
MATCH_TOLERANCE = 0.01  # relative: a carrier or range bin within 1 % is the same radar for the knobs


class CalibrationRow(BaseModel):
    """One calibrated setting: backend options, wall time per simulated second [s] (median over the
    calibration motions) and p(v,t) EMD [m/s] per activity (mean over links and diffuse-phase seeds)."""

    model_config = ConfigDict(extra="forbid")
    label: str
    backend: str
    options: dict = Field(default_factory=dict)
    s_per_sim_s: float
    emd_m_s: dict[str, float]
    emd_sem_m_s: dict[str, float] = Field(default_factory=dict, description="standard error over seeds")
    role: str = Field("candidate", description="default, exact, candidate, points, or measured (in the table "
                      "for the record, never chosen)")

    @model_validator(mode="after")
    def _options_fit_the_backend(self) -> "CalibrationRow":
        from rtchannel.backends.options import validate_options

        validate_options(self.backend, self.options)  # the backend's typed options model
        return self

    def error(self, activity: str | None) -> float:
        """Calibrated EMD [m/s] for `activity` (the worst activity if it was not calibrated)."""
        return self.emd_m_s[self._key(activity)]

    def sem(self, activity: str | None) -> float:
        """Standard error [m/s] of `error(activity)` over the calibration's seeds (0 if unknown)."""
        v = self.emd_sem_m_s.get(self._key(activity), 0.0)
        return v if math.isfinite(v) else 0.0

    def _key(self, activity: str | None) -> str:
        if activity in self.emd_m_s:
            return activity
        return max(self.emd_m_s, key=self.emd_m_s.__getitem__)


class CalibrationTable(BaseModel):
    """Speed and error of a backend's settings for one radar (`rtchannel bench --calibrate`)."""

    model_config = ConfigDict(extra="forbid")
    radar: str = Field(description="what the table was measured for (name)")
    carrier_hz: float
    range_resolution_m: float
    reference: str = Field(description="the converged reference setting and its seed count")
    motions: dict[str, str] = Field(default_factory=dict, description="activity -> calibration motion")
    seeds: int = 1
    single_run_floor_m_s: dict[str, float] = Field(default_factory=dict)
    rows: list[CalibrationRow]

    def row(self, role: str) -> CalibrationRow:
        """The row of `role` ("default" or "exact")."""
        for r in self.rows:
            if r.role == role:
                return r
        raise InputError(f"calibration table for {self.radar} has no {role!r} row")

    def matches(self, carrier_hz: float, range_resolution_m: float) -> bool:
        """Whether a radar with this carrier [Hz] and range bin [m] can use the table."""
        return (abs(carrier_hz / self.carrier_hz - 1) <= MATCH_TOLERANCE
                and abs(range_resolution_m / self.range_resolution_m - 1) <= MATCH_TOLERANCE)

    def digest(self) -> str:
        """Short sha256 of the table's content (identifies it in stored signatures)."""
        return hashlib.sha256(json.dumps(self.model_dump(mode="json"), sort_keys=True).encode()).hexdigest()[:16]


def load_table(path: str | Path) -> CalibrationTable:
    """Read a calibration table (JSON written by `rtchannel bench --calibrate`)."""
    path = Path(path)
    try:
        return CalibrationTable.model_validate_json(path.read_text())
    except FileNotFoundError:
        raise InputError(f"calibration table {path} does not exist") from None
    except ValueError as e:
        raise InputError(f"calibration table {path} is not valid: {str(e).splitlines()[0]}") from None


def shipped_tables() -> list[tuple[Path, CalibrationTable]]:
    """The calibration tables that ship with the package (the presets' radars)."""
    return [(p, load_table(p)) for p in sorted(CALIBRATION_DIR.glob("*.json"))]


def table_for(radar, calibration: str | Path | CalibrationTable | None = None) -> tuple[CalibrationTable, str]:
    """(table, where it came from) for `radar`: the given one, else the shipped table of its carrier and
    range bin. Raises InputError saying how to make one when none matches."""
    wf = radar.waveform
    if isinstance(calibration, CalibrationTable):
        return calibration, "given"
    if calibration is not None:
        return load_table(calibration), str(calibration)
    for path, table in shipped_tables():
        if table.matches(wf.carrier_hz, wf.range_resolution):
            return table, f"shipped:{path.name}"
    raise InputError(f"no calibration table for a {wf.carrier_hz / 1e9:g} GHz radar with {wf.range_resolution:.3g} m "
                     "range bins; make one with `rtchannel bench --calibrate --radar RADAR.yaml --out DIR` and pass "
                     "--calibration DIR/calibration.json")


def parse_budget(accuracy) -> str | float:
    """A budget name or a positive finite EMD [m/s] (strings like "0.1" become numbers)."""
    if isinstance(accuracy, str) and accuracy in BUDGETS:
        return accuracy
    try:
        value = float(accuracy)
    except (TypeError, ValueError):
        raise InputError(f"accuracy must be one of {', '.join(BUDGETS)} or an EMD in m/s, got {accuracy!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"accuracy must be a positive EMD in m/s, got {accuracy!r}")
    return value


# a setting replaces the default (when the default meets the budget too) only if calibrated this much cheaper:
# the seed table's own copy of the default model (walls="auto" with isotropic antennas culls nothing) was
# timed 7 % apart from it, and "no clutter", 4 % cheaper at 24 GHz, missed on a real walk past the chair
MIN_SAVING = 0.10
BALANCED_SIGMAS = 2.0  # "balanced": the excess over the default allowed, in standard errors of the difference


def target(budget: str | float, table: CalibrationTable, activity: str | None,
           row: CalibrationRow | None = None) -> float | None:
    """The EMD limit [m/s] of `budget` for `activity` (None for "exact", which is a setting, not a limit); for
    "balanced" it depends on the standard error of the `row` it is checked against (default: the default's)."""
    if budget == "exact":
        return None
    if budget == "balanced":
        default = table.row("default")
        other = default if row is None else row
        return default.error(activity) + BALANCED_SIGMAS * math.hypot(default.sem(activity), other.sem(activity))
    if budget == "fast":
        return FAST_FACTOR * table.row("default").error(activity)
    return float(budget)


def choose(budget: str | float, backend: str, table: CalibrationTable,
           activity: str | None = None) -> tuple[CalibrationRow, float | None]:
    """(cheapest row of `backend` within the budget on every calibrated activity, the target [m/s] for
    `activity`)."""
    if backend not in {r.backend for r in table.rows}:
        raise InputError(f"the calibration table for {table.radar} has no {backend} settings; --accuracy chooses "
                         f"among: {', '.join(sorted({r.backend for r in table.rows if r.role != 'reference'}))}")
    if budget == "exact":
        return table.row("exact"), None
    default = table.row("default")
    acts = list(default.emd_m_s)

    def meets(r: CalibrationRow) -> bool:
        for a in acts:
            limit = target(budget, table, a, r)
            assert limit is not None  # "exact" returned above: every other budget is a limit
            if not r.emd_m_s.get(a, math.inf) <= limit:
                return False
        return True

    # a row whose errors equal the default's to the last digit made the default's signatures (e.g. walls="auto"
    # with isotropic antennas culls nothing): its other time is the machine's noise, not a saving
    rows = [r for r in table.rows if r.backend == backend and r.role != "measured" and meets(r)
            and (r is default or r.emd_m_s != default.emd_m_s)]
    if not rows:
        limit = target(budget, table, activity)
        best = min((r for r in table.rows if r.backend == backend), key=lambda r: r.error(activity))
        raise InputError(f"no calibrated {backend} setting reaches {limit:.3f} m/s on {activity or 'every activity'} "
                         f"and the budget on every other calibrated activity (best on {activity or 'the worst'}: "
                         f"{best.label}, {best.error(activity):.3f} m/s); raise the budget or use exact")
    if default in rows:  # a saving within the timing noise is no saving: keep today's model
        rows = [r for r in rows if r is default or r.s_per_sim_s <= (1.0 - MIN_SAVING) * default.s_per_sim_s]
    best = min(rows, key=lambda r: (r.s_per_sim_s, r.error(activity)))
    return best, target(budget, table, activity, best)


def resolve(accuracy, backend: str, radar, activity: str | None, options: dict,
            calibration=None) -> tuple[dict, dict]:
    """(backend options, record) for an accuracy budget: the chosen row's options with the user's explicit
    `options` on top, and what to store with the result (budget, target, chosen row, calibrated error and
    cost, table and its digest, overrides)."""
    budget = parse_budget(accuracy)
    if backend == "points":
        raise InputError("--accuracy chooses among a mesh backend's settings; the points backend has none (its "
                         "calibrated error is in the table's points row); use --backend facets")
    table, source = table_for(radar, calibration)
    row, limit = choose(budget, backend, table, activity)
    chosen = dict(row.options)
    overrides = {k: v for k, v in options.items() if k in chosen and chosen[k] != v}
    record = {"budget": budget, "target_emd_m_s": limit, "activity": activity, "chosen": row.label,
              "chosen_options": dict(row.options), "calibrated_emd_m_s": row.error(activity),
              "calibrated_s_per_sim_s": row.s_per_sim_s, "calibration": source, "calibration_radar": table.radar,
              "calibration_digest": table.digest(), "overrides": overrides}
    return {**chosen, **options}, record
