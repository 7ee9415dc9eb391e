#pragma once
// VISLOC_SIMD_CLONES, written before a function, compiles it three times: for AVX-512 (the
// x86-64-v4 level: F, BW, DQ, CD and VL), for AVX2 and for the x86-64 baseline (SSE2). The
// dynamic loader picks the widest version the CPU can run (GCC's target_clones, resolved once
// through an ifunc), so one binary runs everywhere and uses 16- or 8-float vectors where it can.
// The level rather than AVX-512F alone: with BW the 8- and 16-bit integer loops of detection
// (the blur's rows, the Sobel gradients, the maxima masks) run at full width too, detection
// 11% faster on real frames. Every CPU with AVX-512F but Xeon Phi has the level. Only for hot
// loops the compiler vectorizes. No version fuses multiply-adds (the build passes
// -ffp-contract=off, and AVX-512 has FMA): each element goes through the same IEEE operations in
// every version, which therefore give the same bits.
//
// Not under ThreadSanitizer: the loader runs the clones' resolvers before TSan's runtime is up,
// and the instrumented resolvers crash the program at start.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__)
#define VISLOC_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#else
#define VISLOC_SIMD_CLONES
#endif

// GCC's generic vectors for the cloned loops, named by element type and count. A 64-byte vector
// is one AVX-512 register in that clone, two AVX2 or four SSE2 ones in the others; every clone
// applies the same IEEE operations lane by lane. Comparisons of Doubles8 give Int64s8 masks.
// (Pass them through pointers, not by value across a clone boundary: a vector's calling
// convention differs between the clones.)
namespace visloc {
typedef float Floats16 __attribute__((vector_size(64)));
typedef int Ints16 __attribute__((vector_size(64)));
typedef double Doubles8 __attribute__((vector_size(64)));
typedef long long Int64s8 __attribute__((vector_size(64)));
typedef float Floats8 __attribute__((vector_size(32)));
typedef short Shorts8 __attribute__((vector_size(16)));
}  // namespace visloc
