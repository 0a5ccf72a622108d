/* Ryu's shortest round-trip decimal of an IEEE-754 binary32 (float), `f2d`, from ryu/f2s.c and
 * ryu/f2s_intrinsics.h of https://github.com/ulfjack/ryu (commit e3e090c), by Ulf Adams.
 *
 * Copyright 2018 Ulf Adams
 *
 * The contents of this file may be used under the terms of the Apache License,
 * Version 2.0.
 *
 *    (See accompanying file LICENSE-Apache-2.0 or copy at
 *     http://www.apache.org/licenses/LICENSE-2.0)
 *
 * Alternatively, the contents of this file may be used under the terms of
 * the Boost Software License, Version 1.0.
 *    (See https://www.boost.org/LICENSE_1_0.txt)
 *
 * Unless required by applicable law or agreed to in writing, this software
 * is distributed on an "AS IS" BASIS, WITHOUT WARRANTIES OR CONDITIONS OF ANY
 * KIND, either express or implied.
 */
/*
 * Vendored into mavscope (src/mavscope_native/vendor/ryu/). mavscope's changes: only `f2d` and the
 * helpers it needs are kept, with the double tables of ryu_d2d.h (Ryu's default build without
 * RYU_FLOAT_FULL_TABLE: the upper 64 bits of the double tables); the debug printing, `to_chars` and the
 * 32-bit platform branch are removed, the names get an `f32_` prefix; the include guard is mavscope's.
 * mavscope lays the digits out itself (../../fmt.c).
 */
#ifndef MAVSCOPE_RYU_F2D_H
#define MAVSCOPE_RYU_F2D_H

#include <stdbool.h>
#include <stdint.h>

#include "ryu_d2d.h"

#define FLOAT_MANTISSA_BITS 23
#define FLOAT_EXPONENT_BITS 8
#define FLOAT_BIAS 127
#define FLOAT_POW5_INV_BITCOUNT (DOUBLE_POW5_INV_BITCOUNT - 64)
#define FLOAT_POW5_BITCOUNT (DOUBLE_POW5_BITCOUNT - 64)

/* A floating decimal representing mantissa * 10^exponent. */
typedef struct floating_decimal_32 {
  uint32_t mantissa;
  int32_t exponent;
} floating_decimal_32;

static inline uint32_t f32_pow5factor(uint32_t value) {
  uint32_t count = 0;
  for (;;) {
    const uint32_t q = value / 5;
    const uint32_t r = value % 5;
    if (r != 0) {
      break;
    }
    value = q;
    ++count;
  }
  return count;
}

static inline bool f32_multipleOfPowerOf5(const uint32_t value, const uint32_t p) {
  return f32_pow5factor(value) >= p;
}

static inline bool f32_multipleOfPowerOf2(const uint32_t value, const uint32_t p) {
  return (value & ((1u << p) - 1)) == 0;
}

static inline uint32_t f32_mulShift32(const uint32_t m, const uint64_t factor, const int32_t shift) {
  const uint32_t factorLo = (uint32_t)(factor);
  const uint32_t factorHi = (uint32_t)(factor >> 32);
  const uint64_t bits0 = (uint64_t)m * factorLo;
  const uint64_t bits1 = (uint64_t)m * factorHi;
  const uint64_t sum = (bits0 >> 32) + bits1;
  const uint64_t shiftedSum = sum >> (shift - 32);
  return (uint32_t) shiftedSum;
}

static inline uint32_t f32_mulPow5InvDivPow2(const uint32_t m, const uint32_t q, const int32_t j) {
  return f32_mulShift32(m, DOUBLE_POW5_INV_SPLIT[q][1] + 1, j);
}

static inline uint32_t f32_mulPow5divPow2(const uint32_t m, const uint32_t i, const int32_t j) {
  return f32_mulShift32(m, DOUBLE_POW5_SPLIT[i][1], j);
}

/* The shortest decimal that reads back (round to nearest, ties to even) as the float of these bits,
 * the nearest to it among the shortest; for finite non-zero floats only. */
static inline floating_decimal_32 f2d(const uint32_t ieeeMantissa, const uint32_t ieeeExponent) {
  int32_t e2;
  uint32_t m2;
  if (ieeeExponent == 0) {
    e2 = 1 - FLOAT_BIAS - FLOAT_MANTISSA_BITS - 2;
    m2 = ieeeMantissa;
  } else {
    e2 = (int32_t) ieeeExponent - FLOAT_BIAS - FLOAT_MANTISSA_BITS - 2;
    m2 = (1u << FLOAT_MANTISSA_BITS) | ieeeMantissa;
  }
  const bool even = (m2 & 1) == 0;
  const bool acceptBounds = even;

  const uint32_t mv = 4 * m2;
  const uint32_t mp = 4 * m2 + 2;
  const uint32_t mmShift = ieeeMantissa != 0 || ieeeExponent <= 1;
  const uint32_t mm = 4 * m2 - 1 - mmShift;

  uint32_t vr, vp, vm;
  int32_t e10;
  bool vmIsTrailingZeros = false;
  bool vrIsTrailingZeros = false;
  uint8_t lastRemovedDigit = 0;
  if (e2 >= 0) {
    const uint32_t q = log10Pow2(e2);
    e10 = (int32_t) q;
    const int32_t k = FLOAT_POW5_INV_BITCOUNT + pow5bits((int32_t) q) - 1;
    const int32_t i = -e2 + (int32_t) q + k;
    vr = f32_mulPow5InvDivPow2(mv, q, i);
    vp = f32_mulPow5InvDivPow2(mp, q, i);
    vm = f32_mulPow5InvDivPow2(mm, q, i);
    if (q != 0 && (vp - 1) / 10 <= vm / 10) {
      const int32_t l = FLOAT_POW5_INV_BITCOUNT + pow5bits((int32_t) (q - 1)) - 1;
      lastRemovedDigit = (uint8_t) (f32_mulPow5InvDivPow2(mv, q - 1, -e2 + (int32_t) q - 1 + l) % 10);
    }
    if (q <= 9) {
      if (mv % 5 == 0) {
        vrIsTrailingZeros = f32_multipleOfPowerOf5(mv, q);
      } else if (acceptBounds) {
        vmIsTrailingZeros = f32_multipleOfPowerOf5(mm, q);
      } else {
        vp -= f32_multipleOfPowerOf5(mp, q);
      }
    }
  } else {
    const uint32_t q = log10Pow5(-e2);
    e10 = (int32_t) q + e2;
    const int32_t i = -e2 - (int32_t) q;
    const int32_t k = pow5bits(i) - FLOAT_POW5_BITCOUNT;
    int32_t j = (int32_t) q - k;
    vr = f32_mulPow5divPow2(mv, (uint32_t) i, j);
    vp = f32_mulPow5divPow2(mp, (uint32_t) i, j);
    vm = f32_mulPow5divPow2(mm, (uint32_t) i, j);
    if (q != 0 && (vp - 1) / 10 <= vm / 10) {
      j = (int32_t) q - 1 - (pow5bits(i + 1) - FLOAT_POW5_BITCOUNT);
      lastRemovedDigit = (uint8_t) (f32_mulPow5divPow2(mv, (uint32_t) (i + 1), j) % 10);
    }
    if (q <= 1) {
      vrIsTrailingZeros = true;
      if (acceptBounds) {
        vmIsTrailingZeros = mmShift == 1;
      } else {
        --vp;
      }
    } else if (q < 31) {
      vrIsTrailingZeros = f32_multipleOfPowerOf2(mv, q - 1);
    }
  }

  int32_t removed = 0;
  uint32_t output;
  if (vmIsTrailingZeros || vrIsTrailingZeros) {
    while (vp / 10 > vm / 10) {
      vmIsTrailingZeros &= vm % 10 == 0;
      vrIsTrailingZeros &= lastRemovedDigit == 0;
      lastRemovedDigit = (uint8_t) (vr % 10);
      vr /= 10;
      vp /= 10;
      vm /= 10;
      ++removed;
    }
    if (vmIsTrailingZeros) {
      while (vm % 10 == 0) {
        vrIsTrailingZeros &= lastRemovedDigit == 0;
        lastRemovedDigit = (uint8_t) (vr % 10);
        vr /= 10;
        vp /= 10;
        vm /= 10;
        ++removed;
      }
    }
    if (vrIsTrailingZeros && lastRemovedDigit == 5 && vr % 2 == 0) {
      lastRemovedDigit = 4;
    }
    output = vr + ((vr == vm && (!acceptBounds || !vmIsTrailingZeros)) || lastRemovedDigit >= 5);
  } else {
    while (vp / 10 > vm / 10) {
      lastRemovedDigit = (uint8_t) (vr % 10);
      vr /= 10;
      vp /= 10;
      vm /= 10;
      ++removed;
    }
    output = vr + (vr == vm || lastRemovedDigit >= 5);
  }
  floating_decimal_32 fd;
  fd.exponent = e10 + removed;
  fd.mantissa = output;
  return fd;
}

#endif
