/* gi_container.h - the binary container of every gi tool file (.gip, .gih):
 * header, section table, 16-byte aligned sections, CRC-32s, a META text
 * section; byte layout in docs/formats.md.
 *
 * Writing: build each section's payload in a gi_buf (little-endian puts),
 * gi_writer_new, gi_writer_add / gi_writer_add_buf per section (META from
 * gi_meta_add*), gi_writer_write (temp file beside the target, fsync, rename;
 * nothing is left behind on failure), gi_writer_free. Same sections in the
 * same order give byte-identical files.
 *
 * Reading: gi_reader_open (mmap) or gi_reader_open_memory validates the whole
 * container (magic, major version, sizes, bounds, alignment, zero padding,
 * duplicate ids, every CRC, META syntax) before returning; afterwards only the
 * contents of sections need checking, through a bounds-checked gi_cursor whose
 * errors name file, section and absolute offset. gi_reader_free releases all.
 *
 * Errors: functions return 0 or a GI_EXIT_* code and fill a gi_status:
 * GI_EXIT_DATA for bad files ("scene.gip: offset 4096 (section 'PHOT'):
 * checksum mismatch"), GI_EXIT_SYSTEM for I/O and memory (with strerror),
 * GI_EXIT_USAGE for META values that cannot be recorded (a newline in a path).
 * Invalid section ids or duplicate ids given to the writer are programmer
 * errors (GI_BUG). */
#ifndef GI_CONTAINER_H
#define GI_CONTAINER_H

#include <stddef.h>
#include <stdint.h>

#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

#define GI_CONTAINER_HEADER_SIZE 32 /* bytes of the fixed header */
#define GI_CONTAINER_ENTRY_SIZE 32  /* bytes of one section-table entry */
#define GI_CONTAINER_ALIGN 16       /* every section starts on this boundary */

/* ---- growable little-endian byte buffer ---------------------------------- */

/* A zeroed gi_buf is empty and valid. Allocation failure is sticky: later puts
 * do nothing and gi_buf_ok returns 0 (the writer refuses such a buffer with
 * GI_EXIT_SYSTEM), so callers may check once after building a payload. */
typedef struct gi_buf {
    unsigned char *data;
    size_t len;
    size_t cap;
    int failed; /* an allocation failed */
} gi_buf;

void gi_buf_init(gi_buf *b);                  /* empty buffer */
void gi_buf_release(gi_buf *b);               /* frees the bytes; buffer is empty again */
int gi_buf_ok(const gi_buf *b);               /* 1 unless an allocation failed */
int gi_buf_reserve(gi_buf *b, size_t extra);  /* room for extra more bytes; 0 or -1 */
void gi_buf_put_u8(gi_buf *b, uint8_t v);
void gi_buf_put_u16(gi_buf *b, uint16_t v);
void gi_buf_put_u32(gi_buf *b, uint32_t v);
void gi_buf_put_u64(gi_buf *b, uint64_t v);
void gi_buf_put_i32(gi_buf *b, int32_t v);
void gi_buf_put_i64(gi_buf *b, int64_t v);
void gi_buf_put_f32(gi_buf *b, float v);
void gi_buf_put_f64(gi_buf *b, double v);
void gi_buf_put_bytes(gi_buf *b, const void *p, size_t n);
void gi_buf_put_zeros(gi_buf *b, size_t n);
void gi_buf_put_str(gi_buf *b, const char *s);     /* the characters, no NUL */
void gi_buf_align(gi_buf *b, size_t a);            /* zero-pad len to a multiple of a */
/* Overwrite a value already in the buffer (e.g. a count known only later);
 * off + width must be <= len (programmer error otherwise). */
void gi_buf_set_u32(gi_buf *b, size_t off, uint32_t v);
void gi_buf_set_u64(gi_buf *b, size_t off, uint64_t v);

/* ---- META section ("key=value\n" lines) ---------------------------------- */

/* Keys: 1-127 characters of [A-Za-z0-9._-]; values: any bytes but NUL and
 * newline. Standard keys (docs/formats.md): tool, version, option.<name>,
 * input.<name>, input.<name>.hash. Record only options that change the result
 * (never threads or verbosity), in a fixed order, so files stay reproducible.
 * Errors: GI_EXIT_USAGE for a bad key, a duplicate key or a newline in a
 * value; GI_EXIT_SYSTEM out of memory. */
int gi_meta_add(gi_buf *meta, const char *key, const char *value, gi_status *st);
int gi_meta_addf(gi_buf *meta, const char *key, gi_status *st, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
/* Adds input.<name>=<path> and input.<name>.hash=<16 hex digits of hash>. */
int gi_meta_add_input(gi_buf *meta, const char *name, const char *path, uint64_t hash,
                      gi_status *st);

/* ---- writer --------------------------------------------------------------- */

typedef struct gi_writer gi_writer;

/* magic: exactly 8 bytes (e.g. "GIPHOTON", "GIHVDS\0\0"). NULL if out of memory. */
gi_writer *gi_writer_new(const char magic[8], uint16_t major, uint16_t minor);
void gi_writer_free(gi_writer *w);
void gi_writer_set_flags(gi_writer *w, uint32_t flags); /* header flags, default 0 */
/* Append a section (copied). id: 4 printable ASCII characters, unique. */
int gi_writer_add(gi_writer *w, const char id[4], uint32_t flags, const void *data, size_t size,
                  gi_status *st);
/* Append a section taking over buf's bytes without a copy; buf is left empty.
 * A buffer whose allocation failed gives GI_EXIT_SYSTEM. */
int gi_writer_add_buf(gi_writer *w, const char id[4], uint32_t flags, gi_buf *buf,
                      gi_status *st);
/* Write the file: "<path>.tmp.<pid>" beside path, every write checked, fflush,
 * fsync, fclose, rename. On failure the temp file is removed and an existing
 * file at path is left untouched. May be called more than once. */
int gi_writer_write(gi_writer *w, const char *path, gi_status *st);

/* ---- temp files and signals (also for non-container outputs) ------------- */

/* Install SIGINT/SIGTERM/SIGHUP handlers that unlink every registered temp
 * file, then die by the same signal. Idempotent; keeps signals that are
 * ignored (nohup) ignored. */
void gi_container_install_signal_cleanup(void);
/* "<path>.tmp.<pid>" into out (size n); 0, or -1 if it does not fit. */
int gi_container_temp_path(const char *path, char *out, size_t n);
/* Register a temp file for unlinking on a signal; returns a handle >= 0, or
 * -1 if the registry (8 slots, paths < 4096 bytes) is full. Async-signal safe
 * to unregister; call gi_container_temp_unregister once the file is renamed
 * or removed. */
int gi_container_temp_register(const char *path);
void gi_container_temp_unregister(int handle);

/* ---- reader --------------------------------------------------------------- */

typedef struct gi_reader gi_reader;

typedef struct gi_section_info {
    char id[5];       /* four characters and NUL */
    uint32_t flags;
    uint64_t offset;  /* absolute, in the file */
    uint64_t size;
    uint32_t crc;
} gi_section_info;

/* Open and validate a file of the given magic whose major version must equal
 * supported_major (any minor is accepted). The file is mapped read-only
 * (read into memory if it cannot be mapped); section data stay 16-byte aligned.
 * Errors: GI_EXIT_SYSTEM (open/read, strerror), GI_EXIT_DATA (anything wrong
 * with the contents). On error *out is NULL. */
int gi_reader_open(const char *path, const char magic[8], uint16_t supported_major,
                   gi_reader **out, gi_status *st);
/* Same, from bytes in memory (copied); name is used in messages. */
int gi_reader_open_memory(const void *data, size_t size, const char *name,
                          const char magic[8], uint16_t supported_major, gi_reader **out,
                          gi_status *st);
void gi_reader_free(gi_reader *r);

const char *gi_reader_name(const gi_reader *r);   /* path or name given to open */
uint16_t gi_reader_major(const gi_reader *r);
uint16_t gi_reader_minor(const gi_reader *r);
uint32_t gi_reader_flags(const gi_reader *r);     /* header flags */
uint32_t gi_reader_section_count(const gi_reader *r);
/* Table entry i (0 <= i < count), in file order. 0, or -1 if i is out of range. */
int gi_reader_section_info(const gi_reader *r, uint32_t i, gi_section_info *info);
/* Bytes of section id (valid until gi_reader_free), or NULL if absent. An
 * empty section gives a non-NULL pointer and *size 0. size may be NULL. */
const void *gi_reader_section(const gi_reader *r, const char id[4], size_t *size);
/* Like gi_reader_section, but a missing section is GI_EXIT_DATA
 * ("path: section 'PHOT' missing"). */
int gi_reader_require(const gi_reader *r, const char id[4], const void **data, size_t *size,
                      gi_status *st);
/* Identity of the file: gi_hash64 of header and section table (which hold
 * every section's CRC). For input.<name>.hash of downstream files. */
uint64_t gi_reader_fingerprint(const gi_reader *r);

/* Value of key in the file's META section, or NULL (no such key, or no META).
 * Valid until gi_reader_free. */
const char *gi_reader_meta(const gi_reader *r, const char *key);
/* 0 if META records key with value expected; otherwise GI_EXIT_DATA naming
 * both values and the tool to re-run, e.g. "scene.gip: section 'META': made
 * from scene hash 0123456789abcdef, but the scene given has fedcba9876543210
 * (re-run gi-precompute)". */
int gi_container_check_input(const gi_reader *r, const char *key, const char *expected,
                             gi_status *st);

/* ---- bounds-checked parsing of section contents --------------------------- */

/* Reads little-endian values and never reads past the section. On error the
 * position does not move, *v is zeroed, and the message reads
 * "path: offset N (section 'PHOT'): truncated: need 8 bytes, 3 left" with N
 * the absolute file offset. */
typedef struct gi_cursor {
    const unsigned char *base; /* first byte of the section */
    size_t size;               /* section size */
    size_t pos;                /* next byte to read, relative to base */
    uint64_t file_offset;      /* absolute offset of base in the file */
    const char *name;          /* file name for messages */
    char id[5];                /* section id for messages */
} gi_cursor;

/* Cursor over section id; GI_EXIT_DATA if the section is missing. */
int gi_reader_cursor(const gi_reader *r, const char id[4], gi_cursor *c, gi_status *st);
int gi_cursor_u8(gi_cursor *c, uint8_t *v, gi_status *st);
int gi_cursor_u16(gi_cursor *c, uint16_t *v, gi_status *st);
int gi_cursor_u32(gi_cursor *c, uint32_t *v, gi_status *st);
int gi_cursor_u64(gi_cursor *c, uint64_t *v, gi_status *st);
int gi_cursor_i32(gi_cursor *c, int32_t *v, gi_status *st);
int gi_cursor_i64(gi_cursor *c, int64_t *v, gi_status *st);
int gi_cursor_f32(gi_cursor *c, float *v, gi_status *st);
int gi_cursor_f64(gi_cursor *c, double *v, gi_status *st);
/* Pointer to the next n bytes in place (then skipped). */
int gi_cursor_bytes(gi_cursor *c, const void **p, size_t n, gi_status *st);
int gi_cursor_skip(gi_cursor *c, size_t n, gi_status *st);
/* Check that count elements of elem_size bytes fit in what is left, without
 * overflow, before allocating for them ("photon count 4294967295 x 24 bytes
 * exceeds the 96 bytes left"). what names the count in the message. */
int gi_cursor_check_count(const gi_cursor *c, uint64_t count, size_t elem_size,
                          const char *what, gi_status *st);
size_t gi_cursor_remaining(const gi_cursor *c);
/* GI_EXIT_DATA if bytes are left unparsed at the end of the section. */
int gi_cursor_end(const gi_cursor *c, gi_status *st);
/* Report a content error at the cursor's position: "path: offset N (section
 * 'PHOT'): " followed by the formatted text. Returns GI_EXIT_DATA. */
int gi_cursor_fail(const gi_cursor *c, gi_status *st, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

#ifdef __cplusplus
}
#endif
#endif
