#pragma once
// VISLOC_SIMD_CLONES, written before a function, compiles it three times: for AVX-512, for AVX2
// and for the x86-64 baseline (SSE2). The dynamic loader picks the widest version the CPU can
// run (GCC's target_clones, resolved once through an ifunc), so one binary runs everywhere and
// uses 16- or 8-float vectors where it can. Only for hot loops the compiler vectorizes. No
// version fuses multiply-adds (the build passes -ffp-contract=off, and AVX-512 has FMA): each
// element goes through the same IEEE operations in every version, which therefore give the same
// bits.
//
// Not under ThreadSanitizer: the loader runs the clones' resolvers before TSan's runtime is up,
// and the instrumented resolvers crash the program at start.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__)
#define VISLOC_SIMD_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define VISLOC_SIMD_CLONES
#endif
