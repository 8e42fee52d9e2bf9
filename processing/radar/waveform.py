"""FMCW waveform description (validated) and the quantities derived from it.

Defaults are the seed's Ancortek SDR-KIT 2400T2R4 settings: carrier 24.125 GHz, bandwidth 250 MHz,
sawtooth chirps with chirp duration = PRI = 0.5 ms, 128 complex samples per chirp.
"""
from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator

from processing.constants import C0, DEFAULT_CARRIER_HZ
from processing.errors import InputError

__all__ = ["C0", "Waveform"]  # C0 [m/s]: the one home is processing.constants


class Waveform(BaseModel):
    """One radar's FMCW waveform. All values SI (Hz, s, m).

    `carrier_hz` is the centre of the sweep (24.0-24.25 GHz for the seed's radar), so a chirp starts at
    f0 - B/2; Doppler measured in a range bin then scales with the centre wavelength, as in a real radar.
    The ADC records `samples_per_chirp` complex (IQ) samples at `adc_rate_hz` from the start of each
    chirp, so beat frequencies in [0, adc_rate) are unambiguous. `max_range_m` is the largest
    (bistatic: half the total path) range the user needs; the ADC rate must resolve its beat frequency.
    """

    # Bounds (reasons): the carrier 1 MHz - 1 THz spans every radar band from HF to sub-mm; the bandwidth
    # at most the carrier (a sweep cannot pass through 0 Hz) and 100 GHz; the PRI 1 us - 1 s (faster chirps
    # do not exist in FMCW hardware, slower ones cannot see a moving body; the PRI also sets the chirp
    # count, i.e. the memory, of a simulation); 1 mm - 10 km of range covers rooms to outdoor sites.
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    carrier_hz: float = Field(DEFAULT_CARRIER_HZ, ge=1e6, le=1e12, description="carrier (centre) frequency f0 [Hz]")
    bandwidth_hz: float = Field(250e6, gt=0, le=100e9, description="swept bandwidth B [Hz]")
    pri_s: float = Field(0.5e-3, ge=1e-6, le=1.0, description="pulse (chirp) repetition interval [s]")
    chirp_duration_s: float | None = Field(None, ge=1e-7, le=1.0, description="chirp duration [s]; default = PRI")
    samples_per_chirp: int = Field(128, ge=8, le=16384, description="complex ADC samples per chirp")
    adc_rate_hz: float | None = Field(None, gt=0, le=1e11, description="ADC rate [Hz]; default fills the chirp")
    max_range_m: float = Field(10.0, ge=1e-3, le=1e4, description="largest range the user needs [m]")

    @model_validator(mode="after")
    def _consistent(self) -> "Waveform":
        if self.bandwidth_hz >= 2 * self.carrier_hz:
            raise InputError(f"bandwidth_hz ({self.bandwidth_hz:g} Hz) must be below twice carrier_hz: the "
                             "sweep f0 - B/2 .. f0 + B/2 would pass through 0 Hz")
        if self.chirp_s > self.pri_s * (1 + 1e-9):
            raise InputError(f"chirp_duration_s ({self.chirp_s:g} s) must not exceed pri_s ({self.pri_s:g} s)")
        if self.samples_per_chirp / self.fs > self.chirp_s * (1 + 1e-9):
            raise InputError(
                f"adc_rate_hz too low: {self.samples_per_chirp} samples at {self.fs:g} Hz last longer "
                f"than the chirp ({self.chirp_s:g} s)")
        needed = self.slope * 2 * self.max_range_m / C0
        if self.fs < needed:
            raise InputError(
                f"adc_rate_hz ({self.fs:g} Hz) is below the {needed:g} Hz beat frequency of "
                f"max_range_m = {self.max_range_m:g} m")
        return self

    def __repr__(self) -> str:
        return (f"Waveform({self.carrier_hz / 1e9:.6g} GHz carrier, {self.bandwidth_hz / 1e6:.6g} MHz sweep, PRI "
                f"{self.pri_s * 1e3:.6g} ms, {self.samples_per_chirp} samples at {self.fs / 1e6:.6g} MHz; range bin "
                f"{self.range_resolution:.3g} m up to {self.max_range_m:g} m, v_max {self.v_max:.3g} m/s)")

    @property
    def chirp_s(self) -> float:
        """Chirp duration [s]."""
        return self.pri_s if self.chirp_duration_s is None else self.chirp_duration_s

    @property
    def fs(self) -> float:
        """ADC sampling rate [Hz]."""
        return self.samples_per_chirp / self.chirp_s if self.adc_rate_hz is None else self.adc_rate_hz

    @property
    def slope(self) -> float:
        """Chirp slope gamma [Hz/s]."""
        return self.bandwidth_hz / self.chirp_s

    @property
    def start_hz(self) -> float:
        """Frequency at the start of each chirp, f0 - B/2 [Hz]."""
        return self.carrier_hz - self.bandwidth_hz / 2

    @property
    def wavelength(self) -> float:
        """Carrier wavelength [m]."""
        return C0 / self.carrier_hz

    @property
    def v_max(self) -> float:
        """Largest unambiguous radial velocity lambda / (4 PRI) [m/s]."""
        return self.wavelength / (4 * self.pri_s)

    @property
    def range_resolution(self) -> float:
        """Range-bin spacing c fs / (2 gamma N) [m] (= c / 2B when the ADC fills the chirp)."""
        return C0 * self.fs / (2 * self.slope * self.samples_per_chirp)

    @property
    def max_unambiguous_range(self) -> float:
        """Range whose beat frequency equals the ADC rate [m]; farther targets alias."""
        return C0 * self.fs / (2 * self.slope)

    @property
    def max_unambiguous_delay(self) -> float:
        """Round-trip delay whose beat frequency equals the ADC rate [s]."""
        return self.fs / self.slope

    def velocity_resolution(self, window_chirps: int) -> float:
        """Velocity-bin spacing lambda / (2 W PRI) [m/s] of a slow-time FFT.

        Args:
            window_chirps: the FFT's window W [chirps].
        """
        return self.wavelength / (2 * window_chirps * self.pri_s)
