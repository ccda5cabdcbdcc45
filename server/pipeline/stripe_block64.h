// The stripe stages after the column maxima for a block of 64 neighbouring columns, in
// byte lanes (one lane per column): the window walks are byte compares and mask
// arithmetic, so 64 columns cost what one costs in scalar code. AVX-512 (stripe_block64.cpp)
// or, on CPUs without it, AVX2 (stripe_block64_avx2.cpp). Internal to the CPU extractor
// (stripe_extract.cpp); the result equals extract_stripes_reference's.
#pragma once
#include <cstddef>
#include <cstdint>

#include "pipeline/stripe_extract.h"
#include "pipeline/stripe_prefetch.h"

namespace rangex::stripe {

#if defined(__AVX512BW__) || defined(__AVX2__)
#define RANGEX_STRIPE_BLOCK64 1
// f: one frame of height <= 256 rows; mx / arg: its column maxima and their first rows;
// columns c0 .. c0+63 are written to out at o0 + c0.
void column_block64(const uint8_t* f, int width, int height, int c0, const uint8_t* mx,
                    const uint8_t* arg, const StripeSlot& sl, StripeOutput& out, size_t o0,
                    Prefetch& pf, bool stream);
#endif

}  // namespace rangex::stripe
