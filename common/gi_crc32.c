/* gi_crc32.c - CRC-32 (via zlib) and gi_hash64 fingerprints. */
#define _POSIX_C_SOURCE 200809L
#include "gi_crc32.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <zlib.h>

#include "gi_le.h"

uint32_t gi_crc32_update(uint32_t crc, const void *data, size_t n)
{
    const unsigned char *p = (const unsigned char *)data;
    uLong c = crc;
    /* zlib takes a uInt length; feed huge buffers in 1 GiB pieces. */
    while (n > 0) {
        size_t k = n > ((size_t)1 << 30) ? ((size_t)1 << 30) : n;
        c = crc32(c, p, (uInt)k);
        p += k;
        n -= k;
    }
    return (uint32_t)c;
}

uint32_t gi_crc32(const void *data, size_t n) { return gi_crc32_update(0, data, n); }

int gi_file_crc32(const char *path, uint32_t *crc, gi_status *st)
{
    *crc = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s", path);
    size_t cap = (size_t)1 << 20;
    unsigned char *buf = malloc(cap);
    if (!buf) {
        fclose(f);
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path);
    }
    uint32_t c = 0;
    size_t got;
    while ((got = fread(buf, 1, cap, f)) > 0)
        c = gi_crc32_update(c, buf, got);
    int bad = ferror(f);
    int err = errno;
    free(buf);
    fclose(f);
    if (bad) {
        errno = err;
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: read error", path);
    }
    *crc = c;
    return 0;
}

/* gi_hash64, version 1 (frozen; docs/formats.md "gi_hash64"). Four 64-bit
 * lanes eat 32-byte blocks with a multiply-rotate-multiply round (one
 * independent multiply chain per lane, so about one cycle per byte or better),
 * then the lanes, the length, the remaining 8-byte words and the last 0-7
 * bytes are folded into one value, which a SplitMix64 finaliser avalanches.
 * All loads are little-endian via gi_le_get_u64, so the value does not depend
 * on the host byte order or on the alignment of data. */
#define H_M1 0x9E3779B97F4A7C15ull /* 2^64 / golden ratio, odd */
#define H_M2 0xC2B2AE3D27D4EB4Full
#define H_M3 0x165667B19E3779F9ull
#define H_K0 0x243F6A8885A308D3ull /* fractional digits of pi, lane offsets */
#define H_K1 0x13198A2E03707344ull
#define H_K2 0xA4093822299F31D0ull
#define H_K3 0x082EFA98EC4E6C89ull

static inline uint64_t h_rotl(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }

static inline uint64_t h_round(uint64_t acc, uint64_t w)
{
    acc += w * H_M2;
    acc = h_rotl(acc, 31);
    return acc * H_M1;
}

static inline uint64_t h_final(uint64_t x)
{
    x ^= x >> 30;
    x *= 0xBF58476D1CE4E5B9ull;
    x ^= x >> 27;
    x *= 0x94D049BB133111EBull;
    x ^= x >> 31;
    return x;
}

uint64_t gi_hash64(const void *data, size_t n, uint64_t seed)
{
    const unsigned char *p = (const unsigned char *)data;
    size_t left = n;
    uint64_t h;
    if (left >= 32) {
        uint64_t a = seed ^ H_K0, b = seed ^ H_K1, c = seed ^ H_K2, d = seed ^ H_K3;
        while (left >= 32) {
            a = h_round(a, gi_le_get_u64(p));
            b = h_round(b, gi_le_get_u64(p + 8));
            c = h_round(c, gi_le_get_u64(p + 16));
            d = h_round(d, gi_le_get_u64(p + 24));
            p += 32;
            left -= 32;
        }
        h = h_rotl(a, 1) + h_rotl(b, 7) + h_rotl(c, 12) + h_rotl(d, 18);
        h = (h ^ h_round(0, a)) * H_M1 + H_M3;
        h = (h ^ h_round(0, b)) * H_M1 + H_M3;
        h = (h ^ h_round(0, c)) * H_M1 + H_M3;
        h = (h ^ h_round(0, d)) * H_M1 + H_M3;
    } else {
        h = seed ^ H_M3;
    }
    h += (uint64_t)n;
    while (left >= 8) {
        h ^= h_round(0, gi_le_get_u64(p));
        h = h_rotl(h, 27) * H_M1 + H_M3;
        p += 8;
        left -= 8;
    }
    if (left > 0) {
        uint64_t w = 0;
        for (size_t i = 0; i < left; i++)
            w |= (uint64_t)p[i] << (8 * i);
        h ^= w * H_M2;
        h = h_rotl(h, 23) * H_M1;
    }
    return h_final(h);
}

void gi_hash64_hex(uint64_t h, char out[17])
{
    static const char digits[] = "0123456789abcdef";
    for (int i = 15; i >= 0; i--) {
        out[i] = digits[h & 0xf];
        h >>= 4;
    }
    out[16] = '\0';
}
