"""Error model of the fake Sharp IR sensors behind the ADC board.

True distances (from ray casting the floor plan) become voltages through the sensor's
forward curve (drivers.sharp, near-range ambiguity included), then get white voltage
noise, occasional dropouts (a real GP2Y0A710 now and then reports a spike: the reading
jumps to the no-reflection level or to a random voltage), and the ADC's quantisation.

Default figures: the datasheet gives no noise figure; 10 mV rms matches hobbyist
measurements of this sensor on a 10-bit ADC (a few counts of jitter), and 2 % dropouts
is what makes the usual 3-sample median filter necessary.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drivers.sharp import SharpCurve


@dataclass(frozen=True)
class IrErrorModel:
    """Noise, dropouts and ADC of one board."""

    voltage_noise_v: float = 0.01
    dropout_prob: float = 0.02
    adc_bits: int = 10
    vref_v: float = 5.0
    curve: SharpCurve = field(default_factory=SharpCurve)

    def counts(self, true_ranges_m: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Raw ADC counts the board would read for these true distances (inf = no wall)."""
        v = self.curve.voltage(np.asarray(true_ranges_m, dtype=float))
        v = v + rng.normal(0.0, self.voltage_noise_v, size=v.shape)
        drop = rng.random(v.shape) < self.dropout_prob
        if np.any(drop):
            spike = np.where(rng.random(v.shape) < 0.5, 0.4, rng.uniform(1.0, 3.0, v.shape))
            v = np.where(drop, spike, v)
        full = (1 << self.adc_bits) - 1
        return np.clip(np.round(v / self.vref_v * full), 0, full).astype(np.int64)

    def volts(self, counts: np.ndarray) -> np.ndarray:
        """Voltage of raw counts (what the driver computes)."""
        return np.asarray(counts, dtype=float) * self.vref_v / ((1 << self.adc_bits) - 1)
