"""Deprecated location of the fast-time model: it moved to `processing.fast_time`, the neutral home that the
synthesis, the DSP and the backends all import. Importing a name from here still works for one release and
warns (DeprecationWarning)."""
import warnings

import processing.fast_time as _home


def __getattr__(name: str):
    if name.startswith("__"):
        raise AttributeError(name)
    value = getattr(_home, name)  # AttributeError for names the model never had
    warnings.warn(f"processing.dsp.fast_time.{name} moved to processing.fast_time.{name}", DeprecationWarning,
                  stacklevel=2)
    return value
