// A small, portable pseudo-random generator for the synthetic data generator.
//
// The generator must give identical output for the same seed on every machine and standard
// library, so it does not use <random>'s distributions (whose algorithms are unspecified). The
// engine is SplitMix64 (Steele, Lea and Flood 2014): 64-bit state, one multiply-xorshift per
// draw. Doubles are built from the top 53 bits, so every draw is exact and platform-independent.
#pragma once

#include <cstdint>

namespace sfrt::synth {

class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}

  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1).
  double Uniform() { return static_cast<double>(Next() >> 11) * (1.0 / 9007199254740992.0); }
  // Uniform in [lo, hi).
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  // Uniform integer in [0, n), n > 0 (the tiny modulo bias is irrelevant here).
  int Below(int n) { return static_cast<int>(Next() % static_cast<uint64_t>(n)); }
  // Approximately standard normal: the sum of four uniforms, scaled to unit variance. Only
  // additions and multiplications, so the result does not depend on the maths library.
  double Normalish() {
    double s = Uniform() + Uniform() + Uniform() + Uniform() - 2.0;
    return s * 1.7320508075688772;  // sqrt(3): variance of the sum is 4/12
  }

 private:
  uint64_t state_;
};

// Mixes several values into one seed (for per-sequence, per-frame and per-camera streams).
inline uint64_t MixSeed(uint64_t a, uint64_t b, uint64_t c = 0, uint64_t d = 0) {
  Rng r(a ^ 0x243F6A8885A308D3ull);
  uint64_t h = r.Next();
  for (uint64_t v : {b, c, d}) {
    Rng s(h ^ (v * 0x9E3779B97F4A7C15ull + 0x13198A2E03707344ull));
    h = s.Next();
  }
  return h;
}

}  // namespace sfrt::synth
