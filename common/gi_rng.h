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

/* A sampler for one Monte Carlo sample (a pixel sample, a sensor sample):
 * its first GI_SAMPLER_LD_DIMS 2D draws are points of a (0,2) sequence, so the
 * samples of one pixel stratify the pixel area, the first light sample and
 * the first bounce; later draws come from the PCG stream. Each 2D dimension
 * shuffles the sample index with its own nested uniform (Owen) permutation
 * (hash-based, after Laine-Karras and Burley 2020) so that dimensions are
 * independent, and scrambles the point's digits per pixel. */
#define GI_SAMPLER_LD_DIMS 6
typedef struct gi_sampler {
    gi_rng rng;
    uint64_t stream;   /* which pixel or point: selects the scrambles */
    uint32_t index;    /* which sample of that pixel */
    int dim;           /* 2D draws taken so far */
} gi_sampler;

static inline uint32_t gi_reverse_bits(uint32_t i)
{
    i = (i << 16) | (i >> 16);
    i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
    i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
    i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
    return ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
}

/* A bijection of 32-bit words in which each bit depends only on the bits
 * below it; applied to bit-reversed values it is a nested uniform scramble. */
static inline uint32_t gi_lk_permute(uint32_t x, uint32_t seed)
{
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

static inline uint32_t gi_owen_scramble(uint32_t x, uint32_t seed)
{
    return gi_reverse_bits(gi_lk_permute(gi_reverse_bits(x), seed));
}

static inline void gi_sampler_init(gi_sampler *s, uint64_t seed, uint64_t stream, uint32_t index)
{
    gi_rng_seed(&s->rng, seed, stream, index);
    s->stream = gi_mix64(seed * 0x9e3779b97f4a7c15ULL + stream);
    s->index = index;
    s->dim = 0;
}

static inline float gi_sampler_1d(gi_sampler *s) { return gi_rng_float(&s->rng); }

static inline void gi_sampler_2d(gi_sampler *s, float *u1, float *u2)
{
    if (s->dim < GI_SAMPLER_LD_DIMS) {
        uint64_t h = gi_mix64(s->stream + (uint64_t)(s->dim + 1) * 0x632be59bd9b4e019ULL);
        uint64_t h2 = gi_mix64(h ^ 0x2545f4914f6cdd1dULL);
        uint32_t i = gi_owen_scramble(s->index, (uint32_t)h);
        /* (0,2) point i: van der Corput and the second Sobol dimension, each Owen-scrambled */
        uint32_t a = gi_reverse_bits(i), b = 0, v = 1u << 31;
        for (uint32_t k = i; k; k >>= 1, v ^= v >> 1)
            if (k & 1)
                b ^= v;
        a = gi_owen_scramble(a, (uint32_t)(h >> 32));
        b = gi_owen_scramble(b, (uint32_t)h2);
        *u1 = (float)(a >> 8) * (1.0f / 16777216.0f);
        *u2 = (float)(b >> 8) * (1.0f / 16777216.0f);
        s->dim++;
        return;
    }
    *u1 = gi_rng_float(&s->rng);
    *u2 = gi_rng_float(&s->rng);
}

#ifdef __cplusplus
}
#endif
#endif
