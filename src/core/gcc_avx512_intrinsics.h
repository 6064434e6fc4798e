// SPDX-License-Identifier: Apache-2.0
// Force-included into every translation unit of the project by GCC older than 13 on x86 (see
// the top-level CMakeLists.txt). GCC 12.2, Debian 12's compiler, warns -Wmaybe-uninitialized
// inside its own AVX-512 intrinsics (GCC bug 105593: `__m512 __Y = __Y;` in
// _mm512_undefined_ps and friends) wherever Eigen's AVX-512 kernels are inlined, so a build for
// a target with AVX-512 (-march=x86-64-v4, or -march=native on such a CPU) fails under -Werror;
// -Warray-bounds misfires in the same headers on Eigen's packet loads. Including <immintrin.h>
// first, with those two warnings off, silences them for the lines of GCC's intrinsic headers
// only: the project's own code keeps both warnings.

#pragma once

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Warray-bounds"
#include <immintrin.h>
#pragma GCC diagnostic pop
