#pragma once
// Deterministic hashing and value noise: every random quantity of the simulator is a pure
// function of (seed, coordinates), so output never depends on thread scheduling.

#include <algorithm>
#include <cmath>
#include <cstddef>
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

/// A 256 x 256 table of lattice values: the fractal texture reads it instead of hashing, which
/// is several times faster. Each octave reads it rotated and offset by its own seed, so the
/// 256-cell period does not show as a visible repeat.
struct LatticeTable {
    float v[256 * 256];
    LatticeTable() {
        for (uint32_t i = 0; i < 256 * 256; ++i)
            v[i] = static_cast<float>(unit(mix32(i + 0x51ED27U)));
    }
};

inline const LatticeTable& latticeTable() {
    static const LatticeTable table;
    return table;
}

/// Value noise from the table, cubic interpolation, analytic derivatives.
inline NoiseSample tableNoise(double x, double y) {
    const float* T = latticeTable().v;
    const double fx = std::floor(x), fy = std::floor(y);
    const int ix = static_cast<int>(static_cast<int64_t>(fx) & 255);
    const int iy = static_cast<int>(static_cast<int64_t>(fy) & 255);
    const int ix1 = (ix + 1) & 255, iy1 = (iy + 1) & 255;
    const double tx = x - fx, ty = y - fy;
    const double ux = tx * tx * (3 - 2 * tx), uy = ty * ty * (3 - 2 * ty);
    const double dux = 6 * tx * (1 - tx), duy = 6 * ty * (1 - ty);
    const double a = T[iy * 256 + ix], b = T[iy * 256 + ix1];
    const double c = T[iy1 * 256 + ix], d = T[iy1 * 256 + ix1];
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
            // Per-octave rotation (about 37 deg apart) and offset decorrelate the layers.
            // cos and sin of 0.65 * o rad, o = 0..7.
            static constexpr double kCos[8] = {1.0,        0.7960838,  0.2674988,  -0.3701808,
                                               -0.8568888, -0.9941297, -0.7259323, -0.1616762};
            static constexpr double kSin[8] = {0.0,       0.6051864,  0.9635582,  0.9289597,
                                               0.5155014, -0.1081951, -0.6877662, -0.9868439};
            const uint32_t h = mix32(seed * 0x9E3779B1U + o);
            const double c = kCos[o & 7], s = kSin[o & 7];
            const double X = (c * x - s * y) * f + 256.0 * unit(mix32(h + 1));
            const double Y = (s * x + c * y) * f + 256.0 * unit(mix32(h + 2));
            const NoiseSample n = tableNoise(X, Y);
            sum += amp * n.v;
            // Back to map axes: d/dx = f (c dX - ... ) through the rotation.
            dx += amp * f * (c * n.dx + s * n.dy);
            dy += amp * f * (-s * n.dx + c * n.dy);
        } else {
            sum += amp * 0.5;  // the mean of the layers too fine to see
        }
        amp *= gain;
        wavelength /= 2.03;
    }
    return {sum / norm, dx / norm, dy / norm};
}

/// Approximately standard normal from one hash (Irwin-Hall sum of four 8-bit uniforms).
inline double fastGaussian(uint32_t h) {
    const double sum = (h & 255) + ((h >> 8) & 255) + ((h >> 16) & 255) + (h >> 24);
    return (sum / 255.0 - 2.0) * 1.7320508;
}

inline double smoothstep(double e0, double e1, double x) {
    const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3 - 2 * t);
}

}  // namespace lookup::sim::detail
