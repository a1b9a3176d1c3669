/* gi_rng.h - deterministic random numbers, seeded by what is being sampled
 * (pixel, sample index, point), never by thread, so results do not depend on -j.
 * PCG32 (O'Neill 2014) with a 64-bit state; header only. */
#ifndef GI_RNG_H
#define GI_RNG_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_rng { uint64_t state, inc; } gi_rng;

/* SplitMix64 finaliser: a good 64-bit mix for building seeds from indices. */
static inline uint64_t gi_mix64(uint64_t z)
{
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static inline uint32_t gi_rng_u32(gi_rng *r)
{
    uint64_t old = r->state;
    r->state = old * 6364136223846793005ULL + r->inc;
    uint32_t xorshifted = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31));
}

/* Seed from up to three indices and the user's seed. */
static inline void gi_rng_seed(gi_rng *r, uint64_t seed, uint64_t a, uint64_t b)
{
    r->state = 0;
    r->inc = (gi_mix64(seed ^ gi_mix64(a)) << 1u) | 1u;
    gi_rng_u32(r);
    r->state += gi_mix64(gi_mix64(b) ^ (seed * 0x632be59bd9b4e019ULL) ^ a);
    gi_rng_u32(r);
}

/* Uniform float in [0, 1). */
static inline float gi_rng_float(gi_rng *r)
{
    return (float)(gi_rng_u32(r) >> 8) * (1.0f / 16777216.0f);
}
/* Uniform double in [0, 1). */
static inline double gi_rng_double(gi_rng *r)
{
    uint64_t hi = gi_rng_u32(r), lo = gi_rng_u32(r);
    return (double)(((hi << 32) | lo) >> 11) * (1.0 / 9007199254740992.0);
}

/* Radical inverse base 2 and a (0,2) sequence point i of n, XOR-scrambled. */
static inline float gi_vdc(uint32_t i, uint32_t scramble)
{
    i = (i << 16) | (i >> 16);
    i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
    i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
    i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
    i = ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
    return (float)((i ^ scramble) >> 8) * (1.0f / 16777216.0f);
}
static inline float gi_sobol2(uint32_t i, uint32_t scramble)
{
    uint32_t v = 1u << 31, r = 0;
    for (; i; i >>= 1, v ^= v >> 1)
        if (i & 1)
            r ^= v;
    return (float)((r ^ scramble) >> 8) * (1.0f / 16777216.0f);
}

#ifdef __cplusplus
}
#endif
#endif
