#pragma once
// LUMEN_TARGET_CLONES: a function compiled for AVX2 and FMA (x86-64-v3) as well as for the build's baseline, the
// version chosen at load time where the compiler can (GCC's target_clones); elsewhere the baseline only.
#if defined(__x86_64__) && defined(__has_attribute)
#if __has_attribute(target_clones)
#define LUMEN_TARGET_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#endif
#endif
#ifndef LUMEN_TARGET_CLONES
#define LUMEN_TARGET_CLONES
#endif
