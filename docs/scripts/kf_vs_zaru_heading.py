"""Heading error of the true-model bias filter against true-stop ZARU, both with heading hold.

docs/navigation.md ("A better model of the bias is not a better heading"). Independent of
driftless: the simulator's ADIS16405 noise (white N, the Gauss-Markov bank of its bias
instability B, 0.05 deg/s LSB) written again in numpy, the stop-and-go stops (60 s still, then
40 s moving and 20 s still), and each estimator's error while moving. Truth rate 0: the
heading error is the integral of what each method publishes (0 while still: the hold).

    python kf_vs_zaru_heading.py SEED WINDOWS     # numpy 2.4.6; 16 windows take a few minutes

Printed on 2026-11-23 with seed 1, 16 windows: median RMS heading ZARU 0.739, filter 0.818 deg;
RMS bias error while moving ZARU 0.0192, filter 0.0175 deg/s.
"""
import sys

import numpy as np

FS = 100.0
DT = 1 / FS
N = 2.305411529935742 / 60  # deg/sqrt(s)
B = 33.771031140469994 / 3600  # deg/s
LSB = 0.05
S2 = B * B * np.log(2) / np.pi  # variance of each octave's Gauss-Markov state

TCS = []
tc = 0.5 * DT
while len(TCS) < 32 and tc <= 2e5:
    TCS.append(tc)
    tc *= 2
TCS = np.array(TCS)
PHI = np.exp(-DT / TCS)
DRIVE = np.sqrt(S2 * (1 - PHI**2))
M = len(TCS)
LEN = 60000
STILL = np.zeros(LEN, bool)
STILL[:6000] = True
for k in range(9):
    s = 6000 + k * 6000 + 4000
    STILL[s : s + 2000] = True


def simulate(rng):
    g = rng.standard_normal(M) * np.sqrt(S2)
    bias = np.empty(LEN)
    z = rng.standard_normal((LEN, M))
    for i in range(LEN):
        bias[i] = 0.4017 + g.sum()
        g = PHI * g + DRIVE * z[i]
    x = bias + N * np.sqrt(FS) * rng.standard_normal(LEN)
    return np.round(x / LSB) * LSB, bias


def kalman(x):
    """The exact model: a constant turn-on bias (prior sd 1 deg/s) plus the Gauss-Markov bank;
    white noise N^2 fs plus LSB^2/12 per sample; updated with the still samples only."""
    p = np.zeros((M + 1, M + 1))
    p[0, 0] = 1.0
    p[np.arange(1, M + 1), np.arange(1, M + 1)] = S2
    state = np.zeros(M + 1)
    phi = np.concatenate([[1.0], PHI])
    q = np.concatenate([[0.0], S2 * (1 - PHI**2)])
    phi2 = np.outer(phi, phi)
    r = N * N * FS + LSB * LSB / 12
    est = np.empty(LEN)
    for i in range(LEN):
        state = phi * state
        p = p * phi2
        p[np.diag_indices(M + 1)] += q
        if STILL[i]:
            pu = p.sum(1)
            s = pu.sum() + r
            state = state + pu / s * (x[i] - state.sum())
            p = p - np.outer(pu, pu) / s
        est[i] = state.sum()
    return est


def zaru(x):
    """The running mean of each stop, its final mean held while moving."""
    est = np.empty(LEN)
    held = 0.0
    i = 0
    while i < LEN:
        j = i
        while j < LEN and STILL[j] == STILL[i]:
            j += 1
        if STILL[i]:
            m = np.cumsum(x[i:j]) / np.arange(1, j - i + 1)
            est[i:j] = m
            held = m[-1]
        else:
            est[i:j] = held
        i = j
    return est


def main():
    rng = np.random.default_rng(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
    windows = int(sys.argv[2]) if len(sys.argv) > 2 else 6
    res = []
    for w in range(windows):
        x, bias = simulate(rng)
        row = []
        for est in (zaru(x), kalman(x)):
            published = np.where(STILL, 0.0, x - est)
            heading = np.cumsum(published) * DT
            err = (bias - est)[~STILL]
            row.append((np.sqrt((heading**2).mean()), np.sqrt((err**2).mean())))
        res.append(row)
        print(w, "ZARU %.3f deg %.4f deg/s, filter %.3f deg %.4f deg/s" % (*row[0], *row[1]))
    res = np.array(res)
    print(
        "median RMS heading: ZARU %.3f, filter %.3f deg; RMS bias error while moving: ZARU %.4f, filter %.4f deg/s"
        % (
            np.median(res[:, 0, 0]),
            np.median(res[:, 1, 0]),
            np.sqrt((res[:, 0, 1] ** 2).mean()),
            np.sqrt((res[:, 1, 1] ** 2).mean()),
        )
    )


if __name__ == "__main__":
    main()
