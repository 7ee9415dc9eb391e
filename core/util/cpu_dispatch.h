#pragma once
// VISLOC_AVX2_CLONE, written before a function, compiles it twice: for AVX2 and for the x86-64
// baseline (SSE2). The dynamic loader picks the version the CPU can run (GCC's target_clones,
// resolved once through an ifunc), so one binary runs everywhere and uses 8-float vectors where
// it can. Only for hot loops the compiler vectorizes. FMA is not enabled: each element goes
// through the same IEEE operations in both versions, which therefore give the same bits.
//
// Not under ThreadSanitizer: the loader runs the clones' resolvers before TSan's runtime is up,
// and the instrumented resolvers crash the program at start.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__)
#define VISLOC_AVX2_CLONE __attribute__((target_clones("avx2", "default")))
#else
#define VISLOC_AVX2_CLONE
#endif
