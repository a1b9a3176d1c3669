/* gi_le.h - little-endian encoding of integers and IEEE-754 floats, field by field.
 *
 * Every value in a gi binary file goes through these functions; structs are
 * never written or read whole. Integers are assembled from bytes with shifts,
 * so the result is the same on any host byte order and at any alignment.
 * Floats are copied bit for bit (memcpy to an integer of the same width), so
 * NaN payloads, infinities, -0 and subnormals survive a round trip unchanged.
 * put: store into the (at least N-byte) buffer p. get: load from p.
 * No function checks bounds: callers do (gi_cursor in gi_container.h does). */
#ifndef GI_LE_H
#define GI_LE_H

#include <stdint.h>
#include <string.h>

#ifdef __cplusplus
extern "C" {
#endif

static inline void gi_le_put_u8(void *p, uint8_t v) { ((unsigned char *)p)[0] = v; }

static inline void gi_le_put_u16(void *p, uint16_t v)
{
    unsigned char *b = (unsigned char *)p;
    b[0] = (unsigned char)(v & 0xffu);
    b[1] = (unsigned char)(v >> 8);
}

static inline void gi_le_put_u32(void *p, uint32_t v)
{
    unsigned char *b = (unsigned char *)p;
    b[0] = (unsigned char)(v & 0xffu);
    b[1] = (unsigned char)((v >> 8) & 0xffu);
    b[2] = (unsigned char)((v >> 16) & 0xffu);
    b[3] = (unsigned char)(v >> 24);
}

static inline void gi_le_put_u64(void *p, uint64_t v)
{
    unsigned char *b = (unsigned char *)p;
    for (int i = 0; i < 8; i++)
        b[i] = (unsigned char)((v >> (8 * i)) & 0xffu);
}

/* Two's complement, as the integer of the same width. */
static inline void gi_le_put_i32(void *p, int32_t v) { gi_le_put_u32(p, (uint32_t)v); }
static inline void gi_le_put_i64(void *p, int64_t v) { gi_le_put_u64(p, (uint64_t)v); }

static inline void gi_le_put_f32(void *p, float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    gi_le_put_u32(p, u);
}

static inline void gi_le_put_f64(void *p, double v)
{
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    gi_le_put_u64(p, u);
}

static inline uint8_t gi_le_get_u8(const void *p) { return ((const unsigned char *)p)[0]; }

static inline uint16_t gi_le_get_u16(const void *p)
{
    const unsigned char *b = (const unsigned char *)p;
    return (uint16_t)(b[0] | (b[1] << 8));
}

static inline uint32_t gi_le_get_u32(const void *p)
{
    const unsigned char *b = (const unsigned char *)p;
    return (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) |
           ((uint32_t)b[3] << 24);
}

static inline uint64_t gi_le_get_u64(const void *p)
{
    const unsigned char *b = (const unsigned char *)p;
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = (v << 8) | b[i];
    return v;
}

/* Values above INT32_MAX wrap to negative: conversion of an out-of-range
 * unsigned value is implementation-defined in C11, so go through memcpy. */
static inline int32_t gi_le_get_i32(const void *p)
{
    uint32_t u = gi_le_get_u32(p);
    int32_t v;
    memcpy(&v, &u, sizeof v);
    return v;
}

static inline int64_t gi_le_get_i64(const void *p)
{
    uint64_t u = gi_le_get_u64(p);
    int64_t v;
    memcpy(&v, &u, sizeof v);
    return v;
}

static inline float gi_le_get_f32(const void *p)
{
    uint32_t u = gi_le_get_u32(p);
    float v;
    memcpy(&v, &u, sizeof v);
    return v;
}

static inline double gi_le_get_f64(const void *p)
{
    uint64_t u = gi_le_get_u64(p);
    double v;
    memcpy(&v, &u, sizeof v);
    return v;
}

#ifdef __cplusplus
}
#endif
#endif
