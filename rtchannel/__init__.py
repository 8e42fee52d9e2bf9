"""rtchannel: human motion -> skinned body -> scattering paths -> FMCW MIMO radar signatures (upper layer)."""
__version__ = "0.1.0"
