"""Physical constants and the project's default carrier: the one home of each value (SI units).

Everything else imports them from here (`processing.radar.waveform.C0` and the receiver's `K_BOLTZMANN`,
`T0_K` are the same objects, kept under their old names).
"""
SPEED_OF_LIGHT_M_S = 299_792_458.0  # c [m/s], exact (SI definition of the metre)
C0 = SPEED_OF_LIGHT_M_S  # the short name the formulas use
EPSILON_0_F_M = 8.8541878188e-12  # vacuum permittivity [F/m] (CODATA 2022, = scipy.constants.epsilon_0)
K_BOLTZMANN_J_K = 1.380649e-23  # Boltzmann constant [J/K], exact (SI 2019)
T0_K = 290.0  # reference temperature of a noise figure [K] (IEEE)

# The seed's radar (Ancortek SDR-KIT 2400T2R4): carrier at the centre of its 24.0-24.25 GHz sweep [Hz]. The
# default of `Waveform.carrier_hz` and of every function that takes a carrier for the seed's kit.
DEFAULT_CARRIER_HZ = 24.125e9
