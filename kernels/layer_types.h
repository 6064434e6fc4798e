// SPDX-License-Identifier: Apache-2.0
// Types and the wind noise of the layer stage (docs/commands.md, "Layering"), shared by the host
// (src/devices/host/host_wind.cpp, the reference) and the device (kernels/mix.cl,
// kernels/wind.cl). The OpenCL programs get this text as their first source; the host includes it.
// Both sides run the very same float operations in the same order (the kernels switch off
// FP_CONTRACT), so the device and the host reference agree to the rounding of tanh() in the
// clearance limit.
#ifndef DRIVENSHAPE_LAYER_TYPES_H
#define DRIVENSHAPE_LAYER_TYPES_H

#ifdef __cplusplus
#include <cmath>
#include <cstdint>
namespace drivenshape {
typedef std::int32_t ds_int;
typedef std::uint32_t ds_uint;
#define DS_LAYER_FN inline
#define DS_FLOORF(x) std::floor(x)
#define DS_SQRTF(x) std::sqrt(x)
#define DS_TANHF(x) std::tanh(x)
#define DS_WIND_OFFSETS const float*
#define DS_WIND_PARAMS const DsWindParams&
#else
typedef int ds_int;
typedef uint ds_uint;
#define DS_LAYER_FN static inline
#define DS_FLOORF(x) floor(x)
#define DS_SQRTF(x) sqrt(x)
#define DS_TANHF(x) tanh(x)
#define DS_WIND_OFFSETS __global const float*
#define DS_WIND_PARAMS const DsWindParams
#endif

// Most octaves of the wind noise; each octave doubles the frequency and halves the amplitude.
#define DS_WIND_MAX_OCTAVES 8
// The noise lattice repeats every DS_WIND_PERIOD cells on each axis, so the host can reduce the
// advection offset modulo the period in double (long shots keep their float precision).
#define DS_WIND_PERIOD 256
// The clearance limit keeps every wind displacement below this fraction of the vertex's
// distance to the driver surface: |d'| = k c tanh(|d| / (k c)) < k c < c.
#define DS_WIND_CLEARANCE_FRACTION 0.9f

// Scalars of one dsMix launch (passed by value).
typedef struct DsMixParams {
  ds_int vertexCount;  // Vd
  ds_int frameCount;   // F
} DsMixParams;

// Scalars of one dsWind launch (passed by value). Per-frame offsets come in a buffer:
//   offsets  F x DS_WIND_MAX_OCTAVES x 4 floats: octave o of frame f at [(f * MAX + o) * 4],
//            xyz = the advection offset of that octave's lattice coordinates, reduced modulo
//            DS_WIND_PERIOD (w unused).
typedef struct DsWindParams {
  ds_int vertexCount;   // Vd
  ds_int frameCount;    // F
  ds_int octaves;       // 1 .. DS_WIND_MAX_OCTAVES
  ds_uint seed;         // --wind-seed
  float amplitude;      // scene units, divided by the octave gain sum (see dsWindNoise)
  float frequency;      // lattice cells per scene unit of the first octave
  ds_int hasClearance;  // 0: no clearance limit
  ds_int pad0;
} DsWindParams;

// ---- The noise: value noise on an integer lattice with quintic fade, three channels. ----

// Lattice hash: murmur3's finaliser over the wrapped cell and the seed. Its low 30 bits give the
// three channels' lattice values (10 bits each).
DS_LAYER_FN ds_uint dsWindHash(ds_int ix, ds_int iy, ds_int iz, ds_uint seed) {
  ds_uint h = seed * 0x9E3779B9u;
  h ^= ((ds_uint)ix & (DS_WIND_PERIOD - 1)) * 0x85EBCA6Bu;
  h ^= ((ds_uint)iy & (DS_WIND_PERIOD - 1)) * 0xC2B2AE35u;
  h ^= ((ds_uint)iz & (DS_WIND_PERIOD - 1)) * 0x27D4EB2Fu;
  h ^= h >> 16;
  h *= 0x85EBCA6Bu;
  h ^= h >> 13;
  h *= 0xC2B2AE35u;
  h ^= h >> 16;
  return h;
}

// Lattice value of channel c (0..2) from a hash: 10 bits mapped to [-1, 1] (to one rounding).
DS_LAYER_FN float dsWindChannelValue(ds_uint hash, ds_int channel) {
  return (float)((hash >> (10 * channel)) & 1023u) * (2.0f / 1023.0f) - 1.0f;
}

// 6t^5 - 15t^4 + 10t^3: C2 at cell borders; its slope is at most 15/8 (at t = 1/2).
DS_LAYER_FN float dsWindFade(float t) {
  return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f);
}

DS_LAYER_FN float dsWindLerp(float a, float b, float t) {
  return a + t * (b - a);
}

// Value noise of the three channels at lattice coordinates (x, y, z), added to `out` times
// `gain`. Each channel is in [-1, 1], continuous, and |d noise / d x_i| <= 2 * 15/8 = 3.75 on
// every axis (the slope of the fade times the largest difference of two lattice values). One
// hash per cell corner serves all three channels.
DS_LAYER_FN void dsWindValueNoise(float x, float y, float z, ds_uint seed, float gain, float* out) {
  const float fx = DS_FLOORF(x);
  const float fy = DS_FLOORF(y);
  const float fz = DS_FLOORF(z);
  const ds_int ix = (ds_int)fx;
  const ds_int iy = (ds_int)fy;
  const ds_int iz = (ds_int)fz;
  const float tx = dsWindFade(x - fx);
  const float ty = dsWindFade(y - fy);
  const float tz = dsWindFade(z - fz);
  const ds_uint h000 = dsWindHash(ix, iy, iz, seed);
  const ds_uint h100 = dsWindHash(ix + 1, iy, iz, seed);
  const ds_uint h010 = dsWindHash(ix, iy + 1, iz, seed);
  const ds_uint h110 = dsWindHash(ix + 1, iy + 1, iz, seed);
  const ds_uint h001 = dsWindHash(ix, iy, iz + 1, seed);
  const ds_uint h101 = dsWindHash(ix + 1, iy, iz + 1, seed);
  const ds_uint h011 = dsWindHash(ix, iy + 1, iz + 1, seed);
  const ds_uint h111 = dsWindHash(ix + 1, iy + 1, iz + 1, seed);
  for (ds_int c = 0; c < 3; ++c) {
    const float x00 = dsWindLerp(dsWindChannelValue(h000, c), dsWindChannelValue(h100, c), tx);
    const float x10 = dsWindLerp(dsWindChannelValue(h010, c), dsWindChannelValue(h110, c), tx);
    const float x01 = dsWindLerp(dsWindChannelValue(h001, c), dsWindChannelValue(h101, c), tx);
    const float x11 = dsWindLerp(dsWindChannelValue(h011, c), dsWindChannelValue(h111, c), tx);
    out[c] += gain * dsWindLerp(dsWindLerp(x00, x10, ty), dsWindLerp(x01, x11, ty), tz);
  }
}

// The wind displacement of one point (before the weight and the clearance limit), channel c:
//
//   d_c = amplitude * sum_o 0.5^o noise_c(2^o frequency p + offset_o)
//
// with p the vertex's rest position (centred) and offset_o the octave's advection offset for
// this frame; the host passes amplitude already divided by sum_o 0.5^o, so |d_c| <= the user's
// amplitude. `offsets` points at this frame's DS_WIND_MAX_OCTAVES x 4 floats.
DS_LAYER_FN void dsWindDisplacement(const float* rest, DS_WIND_OFFSETS offsets,
                                    DS_WIND_PARAMS params, float* out) {
  float scale = params.frequency;
  float gain = 1.0f;
  out[0] = 0.0f;
  out[1] = 0.0f;
  out[2] = 0.0f;
  for (ds_int o = 0; o < params.octaves; ++o) {
    const float x = scale * rest[0] + offsets[4 * o + 0];
    const float y = scale * rest[1] + offsets[4 * o + 1];
    const float z = scale * rest[2] + offsets[4 * o + 2];
    dsWindValueNoise(x, y, z, params.seed, gain, out);
    scale *= 2.0f;
    gain *= 0.5f;
  }
  out[0] *= params.amplitude;
  out[1] *= params.amplitude;
  out[2] *= params.amplitude;
}

// Adds the weighted displacement to `position`, limited by the clearance c (the vertex's
// distance to the driver surface) when `hasClearance`:
//
//   d = weight * displacement;   |d| -> k c tanh(|d| / (k c)),  k = DS_WIND_CLEARANCE_FRACTION
//
// The limit is smooth, nearly the identity while |d| << c, and below k c < c always, so the
// moved point stays inside the open ball of radius c around the old one, which holds no point
// of the surface: the wind cannot push cloth through the body. A zero displacement leaves the
// position untouched (bitwise), so amplitude 0 or weight 0 changes nothing.
DS_LAYER_FN void dsWindApply(float* position, const float* displacement, float weight,
                             float clearance, ds_int hasClearance) {
  float d0 = weight * displacement[0];
  float d1 = weight * displacement[1];
  float d2 = weight * displacement[2];
  const float length2 = d0 * d0 + d1 * d1 + d2 * d2;
  if (!(length2 > 0.0f)) {
    return;
  }
  if (hasClearance) {
    const float limit = DS_WIND_CLEARANCE_FRACTION * clearance;
    if (!(limit > 0.0f)) {
      return;
    }
    const float length = DS_SQRTF(length2);
    const float scale = limit * DS_TANHF(length / limit) / length;
    d0 *= scale;
    d1 *= scale;
    d2 *= scale;
  }
  position[0] += d0;
  position[1] += d1;
  position[2] += d2;
}

#ifdef __cplusplus
static_assert(sizeof(DsMixParams) == 8, "DsMixParams layout differs from the device");
static_assert(sizeof(DsWindParams) == 32, "DsWindParams layout differs from the device");
}  // namespace drivenshape
#endif

#endif
