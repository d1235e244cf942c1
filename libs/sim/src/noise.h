#pragma once
// Deterministic hashing and value noise: every random quantity of the simulator is a pure
// function of (seed, coordinates), so output never depends on thread scheduling.

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace lookup::sim::detail {

inline uint32_t mix32(uint32_t h) {
    h ^= h >> 16;
    h *= 0x7feb352dU;
    h ^= h >> 15;
    h *= 0x846ca68bU;
    h ^= h >> 16;
    return h;
}

inline uint32_t hash2(int32_t x, int32_t y, uint32_t seed) {
    return mix32(static_cast<uint32_t>(x) * 0x9E3779B1U ^
                 mix32(static_cast<uint32_t>(y) ^ seed * 0x85EBCA77U));
}

inline uint32_t hash3(uint32_t a, uint32_t b, uint32_t c) {
    return mix32(a * 0x9E3779B1U ^ mix32(b * 0x85EBCA77U ^ mix32(c + 0x27d4eb2fU)));
}

/// Uniform in [0, 1).
inline double unit(uint32_t h) { return (h >> 8) * (1.0 / 16777216.0); }

/// Standard normal from two hashes (Box-Muller).
inline double gaussian(uint32_t h1, uint32_t h2) {
    const double u1 = (unit(h1) + 1e-7);
    const double u2 = unit(h2);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

struct NoiseSample {
    double v;   ///< value in [0, 1]
    double dx;  ///< d v / d x (per unit of the noise coordinates)
    double dy;
};

/// 2-D value noise on the unit lattice with quintic interpolation and analytic derivatives.
inline NoiseSample valueNoise(double x, double y, uint32_t seed) {
    const double fx = std::floor(x), fy = std::floor(y);
    const int32_t ix = static_cast<int32_t>(fx), iy = static_cast<int32_t>(fy);
    const double tx = x - fx, ty = y - fy;
    const double ux = tx * tx * tx * (tx * (tx * 6 - 15) + 10);
    const double uy = ty * ty * ty * (ty * (ty * 6 - 15) + 10);
    const double dux = 30 * tx * tx * (tx - 1) * (tx - 1);
    const double duy = 30 * ty * ty * (ty - 1) * (ty - 1);
    const double a = unit(hash2(ix, iy, seed)), b = unit(hash2(ix + 1, iy, seed));
    const double c = unit(hash2(ix, iy + 1, seed)), d = unit(hash2(ix + 1, iy + 1, seed));
    const double k = a - b - c + d;
    return {a + (b - a) * ux + (c - a) * uy + k * ux * uy, dux * ((b - a) + k * uy),
            duy * ((c - a) + k * ux)};
}

/// Fractal sum of `octaves` value-noise layers, first wavelength `wavelength`, each next one
/// 1/2.03 of it with amplitude `gain` times smaller. Layers whose wavelength is below
/// `min_wavelength` (about two pixel footprints) are left out, which is the anti-aliasing.
/// Value in [0, 1] around 0.5; derivatives per metre.
inline NoiseSample fbm(double x, double y, uint32_t seed, int octaves, double wavelength,
                       double gain, double min_wavelength) {
    double sum = 0, dx = 0, dy = 0, amp = 1, norm = 0;
    for (int o = 0; o < octaves; ++o) {
        norm += amp;
        if (wavelength >= min_wavelength) {
            const double f = 1.0 / wavelength;
            const NoiseSample n = valueNoise(x * f + o * 17.13, y * f - o * 31.7, seed + o * 101);
            sum += amp * n.v;
            dx += amp * n.dx * f;
            dy += amp * n.dy * f;
        } else {
            sum += amp * 0.5;  // the mean of the layers too fine to see
        }
        amp *= gain;
        wavelength /= 2.03;
    }
    return {sum / norm, dx / norm, dy / norm};
}

inline double smoothstep(double e0, double e1, double x) {
    const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3 - 2 * t);
}

}  // namespace lookup::sim::detail
