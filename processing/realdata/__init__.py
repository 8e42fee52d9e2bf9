"""Real radar data: Ancortek recordings and real micro-Doppler spectrogram images (Glasgow dataset)."""
