"""splitmix64 as the fixture scripts share it: uniform doubles in [0, 1), bit-identical to the
library's `driftless::synthetic::SplitMix64` (so a test can make the same inputs without storing
them). Imported by the gen_*_fixture(s).py scripts beside it; needs nothing but Python."""

MASK = (1 << 64) - 1


def splitmix64(seed):
    """Endless uniform doubles (z >> 11) * 2**-53 from a 64-bit seed."""
    state = seed & MASK
    while True:
        state = (state + 0x9E3779B97F4A7C15) & MASK
        z = state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
        z ^= z >> 31
        yield (z >> 11) * 2.0 ** -53
