/* gi_crc32.h - checksums and fingerprints: CRC-32 for file integrity, a
 * 64-bit hash for input identities recorded in META sections.
 *
 * CRC-32 is zlib's crc32() (the ISO-HDLC / PNG / gzip CRC, reflected,
 * polynomial 0xEDB88320, initial value 0, "123456789" -> 0xCBF43926).
 * gi_hash64 is gi's own 64-bit hash (specified in docs/formats.md); its
 * values are stored in files, so the algorithm is frozen: changing it makes
 * every stored hash stale. Both are deterministic and host-independent. */
#ifndef GI_CRC32_H
#define GI_CRC32_H

#include <stddef.h>
#include <stdint.h>

#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Continue a CRC-32 over n more bytes; start with crc = 0. Any n (chunks
 * internally to zlib's 32-bit length). */
uint32_t gi_crc32_update(uint32_t crc, const void *data, size_t n);
/* CRC-32 of one buffer: gi_crc32_update(0, data, n). */
uint32_t gi_crc32(const void *data, size_t n);
/* CRC-32 of a whole file's contents. Errors: GI_EXIT_SYSTEM "path: strerror". */
int gi_file_crc32(const char *path, uint32_t *crc, gi_status *st);

/* 64-bit non-cryptographic hash of n bytes. Hash several arrays as one
 * fingerprint by chaining: h = gi_hash64(b, nb, gi_hash64(a, na, seed)). */
uint64_t gi_hash64(const void *data, size_t n, uint64_t seed);
/* 16 lowercase hex digits plus NUL, most significant digit first. */
void gi_hash64_hex(uint64_t h, char out[17]);

#ifdef __cplusplus
}
#endif
#endif
