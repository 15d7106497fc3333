#pragma once
// Attributes for the integrator's hot loops (spring_kernels.cpp, cg_solver.cpp).

// The hot loops are compiled twice, for AVX2 and for the generic x86-64 baseline, and picked at
// load time (no -march: the binary runs on any x86-64). Neither clone uses FMA and every
// reduction keeps the same per-lane order, so both give the same bits. Not under a sanitizer: the
// clones' ifunc resolver runs during relocation, before the sanitizer's runtime is up, and
// crashes (tools/sanitize.sh).
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__) && \
    !defined(__SANITIZE_THREAD__) && !defined(__SANITIZE_ADDRESS__)
#define BISTURI_HOT [[gnu::target_clones("avx2", "default")]]
#else
#define BISTURI_HOT
#endif
#define BISTURI_INLINE [[gnu::always_inline]] inline
