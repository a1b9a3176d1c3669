/* gi_container.c - write and validate gi container files (docs/formats.md). */
#define _POSIX_C_SOURCE 200809L
#include "gi_container.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <signal.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gi_crc32.h"
#include "gi_le.h"
#include "gi_log.h"

#define HDR GI_CONTAINER_HEADER_SIZE
#define ENT GI_CONTAINER_ENTRY_SIZE
#define ALIGN GI_CONTAINER_ALIGN
#define META_KEY_MAX 127

static const unsigned char g_zeros[ALIGN];

static uint64_t align_up(uint64_t x) { return (x + (ALIGN - 1)) & ~(uint64_t)(ALIGN - 1); }

/* ===== gi_buf ============================================================== */

void gi_buf_init(gi_buf *b) { memset(b, 0, sizeof *b); }

void gi_buf_release(gi_buf *b)
{
    if (!b)
        return;
    free(b->data);
    memset(b, 0, sizeof *b);
}

int gi_buf_ok(const gi_buf *b) { return !b->failed; }

int gi_buf_reserve(gi_buf *b, size_t extra)
{
    if (b->failed)
        return -1;
    if (extra <= b->cap - b->len)
        return 0;
    if (extra > SIZE_MAX - b->len) {
        b->failed = 1;
        return -1;
    }
    size_t need = b->len + extra;
    size_t cap = b->cap ? b->cap : 256;
    while (cap < need)
        cap = cap > SIZE_MAX / 2 ? need : cap * 2;
    unsigned char *p = realloc(b->data, cap);
    if (!p) {
        b->failed = 1;
        return -1;
    }
    b->data = p;
    b->cap = cap;
    return 0;
}

/* Room for n bytes at the end; NULL (and sticky failure) if out of memory. */
static unsigned char *buf_grow(gi_buf *b, size_t n)
{
    if (gi_buf_reserve(b, n) != 0)
        return NULL;
    unsigned char *p = b->data + b->len;
    b->len += n;
    return p;
}

void gi_buf_put_u8(gi_buf *b, uint8_t v)
{
    unsigned char *p = buf_grow(b, 1);
    if (p)
        gi_le_put_u8(p, v);
}

void gi_buf_put_u16(gi_buf *b, uint16_t v)
{
    unsigned char *p = buf_grow(b, 2);
    if (p)
        gi_le_put_u16(p, v);
}

void gi_buf_put_u32(gi_buf *b, uint32_t v)
{
    unsigned char *p = buf_grow(b, 4);
    if (p)
        gi_le_put_u32(p, v);
}

void gi_buf_put_u64(gi_buf *b, uint64_t v)
{
    unsigned char *p = buf_grow(b, 8);
    if (p)
        gi_le_put_u64(p, v);
}

void gi_buf_put_i32(gi_buf *b, int32_t v)
{
    unsigned char *p = buf_grow(b, 4);
    if (p)
        gi_le_put_i32(p, v);
}

void gi_buf_put_i64(gi_buf *b, int64_t v)
{
    unsigned char *p = buf_grow(b, 8);
    if (p)
        gi_le_put_i64(p, v);
}

void gi_buf_put_f32(gi_buf *b, float v)
{
    unsigned char *p = buf_grow(b, 4);
    if (p)
        gi_le_put_f32(p, v);
}

void gi_buf_put_f64(gi_buf *b, double v)
{
    unsigned char *p = buf_grow(b, 8);
    if (p)
        gi_le_put_f64(p, v);
}

void gi_buf_put_bytes(gi_buf *b, const void *src, size_t n)
{
    if (n == 0)
        return;
    unsigned char *p = buf_grow(b, n);
    if (p)
        memcpy(p, src, n);
}

void gi_buf_put_zeros(gi_buf *b, size_t n)
{
    if (n == 0)
        return;
    unsigned char *p = buf_grow(b, n);
    if (p)
        memset(p, 0, n);
}

void gi_buf_put_str(gi_buf *b, const char *s) { gi_buf_put_bytes(b, s, strlen(s)); }

void gi_buf_align(gi_buf *b, size_t a)
{
    if (a > 1 && b->len % a != 0)
        gi_buf_put_zeros(b, a - b->len % a);
}

void gi_buf_set_u32(gi_buf *b, size_t off, uint32_t v)
{
    if (b->failed)
        return;
    if (off > b->len || b->len - off < 4)
        GI_BUG("gi_buf_set_u32 outside the buffer");
    gi_le_put_u32(b->data + off, v);
}

void gi_buf_set_u64(gi_buf *b, size_t off, uint64_t v)
{
    if (b->failed)
        return;
    if (off > b->len || b->len - off < 8)
        GI_BUG("gi_buf_set_u64 outside the buffer");
    gi_le_put_u64(b->data + off, v);
}

/* ===== META ================================================================ */

static int meta_key_char(int c)
{
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           c == '.' || c == '_' || c == '-';
}

static int meta_key_valid(const char *k, size_t n)
{
    if (n == 0 || n > META_KEY_MAX)
        return 0;
    for (size_t i = 0; i < n; i++)
        if (!meta_key_char((unsigned char)k[i]))
            return 0;
    return 1;
}

int gi_meta_add(gi_buf *meta, const char *key, const char *value, gi_status *st)
{
    size_t klen = strlen(key);
    if (!meta_key_valid(key, klen))
        return gi_status_set(st, GI_EXIT_USAGE,
                             "meta: key '%.*s' is not 1-127 characters of A-Z a-z 0-9 . _ -",
                             (int)(klen > 64 ? 64 : klen), key);
    if (strchr(value, '\n'))
        return gi_status_set(st, GI_EXIT_USAGE,
                             "meta: value of '%s' contains a newline, which cannot be recorded",
                             key);
    /* Refuse a second line with the same key (readers would refuse the file). */
    const char *p = (const char *)meta->data;
    const char *end = p ? p + meta->len : NULL; /* an empty buffer has no data (NULL + 0 is UB) */
    while (p && p < end) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        const char *le = nl ? nl : end;
        const char *eq = memchr(p, '=', (size_t)(le - p));
        if (eq && (size_t)(eq - p) == klen && memcmp(p, key, klen) == 0)
            return gi_status_set(st, GI_EXIT_USAGE, "meta: key '%s' given twice", key);
        p = nl ? nl + 1 : end;
    }
    gi_buf_put_bytes(meta, key, klen);
    gi_buf_put_u8(meta, '=');
    gi_buf_put_str(meta, value);
    gi_buf_put_u8(meta, '\n');
    if (!gi_buf_ok(meta))
        return gi_status_set(st, GI_EXIT_SYSTEM, "meta: out of memory");
    return 0;
}

int gi_meta_addf(gi_buf *meta, const char *key, gi_status *st, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0)
        return gi_status_set(st, GI_EXIT_USAGE, "meta: cannot format the value of '%s'", key);
    char *s = malloc((size_t)n + 1);
    if (!s)
        return gi_status_set(st, GI_EXIT_SYSTEM, "meta: out of memory");
    va_start(ap, fmt);
    vsnprintf(s, (size_t)n + 1, fmt, ap);
    va_end(ap);
    int rc = gi_meta_add(meta, key, s, st);
    free(s);
    return rc;
}

int gi_meta_add_input(gi_buf *meta, const char *name, const char *path, uint64_t hash,
                      gi_status *st)
{
    char key[META_KEY_MAX + 2];
    char hex[17];
    if ((size_t)snprintf(key, sizeof key, "input.%s.hash", name) >= sizeof key)
        return gi_status_set(st, GI_EXIT_USAGE, "meta: input name '%.64s' too long", name);
    gi_hash64_hex(hash, hex);
    snprintf(key, sizeof key, "input.%s", name);
    int rc = gi_meta_add(meta, key, path, st);
    if (rc)
        return rc;
    snprintf(key, sizeof key, "input.%s.hash", name);
    return gi_meta_add(meta, key, hex, st);
}

/* ===== temp-file registry and signal cleanup =============================== */

#define TEMP_SLOTS 8
#define TEMP_PATH_MAX 4096

/* Slot states: 0 free, 1 being filled or emptied, 2 holds a path to unlink. */
static atomic_int g_temp_state[TEMP_SLOTS];
static char g_temp_path[TEMP_SLOTS][TEMP_PATH_MAX];

int gi_container_temp_register(const char *path)
{
    size_t n = strlen(path);
    if (n >= TEMP_PATH_MAX)
        return -1;
    for (int i = 0; i < TEMP_SLOTS; i++) {
        int expect = 0;
        if (atomic_compare_exchange_strong(&g_temp_state[i], &expect, 1)) {
            memcpy(g_temp_path[i], path, n + 1);
            atomic_store(&g_temp_state[i], 2);
            return i;
        }
    }
    return -1;
}

void gi_container_temp_unregister(int handle)
{
    if (handle >= 0 && handle < TEMP_SLOTS)
        atomic_store(&g_temp_state[handle], 0);
}

int gi_container_temp_path(const char *path, char *out, size_t n)
{
    int k = snprintf(out, n, "%s.tmp.%ld", path, (long)getpid());
    return (k < 0 || (size_t)k >= n) ? -1 : 0;
}

/* Only async-signal-safe calls: unlink, sigaction, raise. */
static void cleanup_on_signal(int sig)
{
    for (int i = 0; i < TEMP_SLOTS; i++)
        if (atomic_load(&g_temp_state[i]) == 2)
            unlink(g_temp_path[i]);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = SIG_DFL;
    sigemptyset(&sa.sa_mask);
    sigaction(sig, &sa, NULL);
    raise(sig); /* delivered with the default action once the handler returns */
}

void gi_container_install_signal_cleanup(void)
{
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        struct sigaction old;
        if (sigaction(sigs[i], NULL, &old) != 0)
            continue;
        /* Keep ignored signals ignored and a handler someone else installed. */
        if (old.sa_handler != SIG_DFL || (old.sa_flags & SA_SIGINFO))
            continue;
        struct sigaction sa;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = cleanup_on_signal;
        sigemptyset(&sa.sa_mask);
        sigaction(sigs[i], &sa, NULL);
    }
}

/* ===== writer ============================================================== */

typedef struct wsection {
    char id[4];
    uint32_t flags;
    unsigned char *data; /* owned; NULL when size is 0 */
    size_t size;
    uint32_t crc;
} wsection;

struct gi_writer {
    char magic[8];
    uint16_t major, minor;
    uint32_t flags;
    wsection *sec;
    size_t n, cap;
};

gi_writer *gi_writer_new(const char magic[8], uint16_t major, uint16_t minor)
{
    gi_writer *w = calloc(1, sizeof *w);
    if (!w)
        return NULL;
    memcpy(w->magic, magic, 8);
    w->major = major;
    w->minor = minor;
    return w;
}

void gi_writer_free(gi_writer *w)
{
    if (!w)
        return;
    for (size_t i = 0; i < w->n; i++)
        free(w->sec[i].data);
    free(w->sec);
    free(w);
}

void gi_writer_set_flags(gi_writer *w, uint32_t flags) { w->flags = flags; }

static int id_valid(const char id[4])
{
    for (int i = 0; i < 4; i++)
        if ((unsigned char)id[i] < 0x20 || (unsigned char)id[i] > 0x7e)
            return 0;
    return 1;
}

/* Append a table entry taking ownership of data (freed on failure). */
static int writer_append(gi_writer *w, const char id[4], uint32_t flags, unsigned char *data,
                         size_t size, gi_status *st)
{
    if (!id_valid(id))
        GI_BUG("section id must be 4 printable ASCII characters");
    for (size_t i = 0; i < w->n; i++)
        if (memcmp(w->sec[i].id, id, 4) == 0)
            GI_BUG("section id added twice");
    if (w->n >= UINT32_MAX) {
        free(data);
        return gi_status_set(st, GI_EXIT_USAGE, "writer: too many sections");
    }
    if (w->n == w->cap) {
        size_t cap = w->cap ? w->cap * 2 : 8;
        wsection *s = realloc(w->sec, cap * sizeof *s);
        if (!s) {
            free(data);
            return gi_status_set(st, GI_EXIT_SYSTEM, "writer: out of memory");
        }
        w->sec = s;
        w->cap = cap;
    }
    wsection *s = &w->sec[w->n++];
    memcpy(s->id, id, 4);
    s->flags = flags;
    s->data = data;
    s->size = size;
    s->crc = gi_crc32(data, size);
    return 0;
}

int gi_writer_add(gi_writer *w, const char id[4], uint32_t flags, const void *data, size_t size,
                  gi_status *st)
{
    unsigned char *copy = NULL;
    if (size > 0) {
        copy = malloc(size);
        if (!copy)
            return gi_status_set(st, GI_EXIT_SYSTEM, "writer: section '%.4s': out of memory", id);
        memcpy(copy, data, size);
    }
    return writer_append(w, id, flags, copy, size, st);
}

int gi_writer_add_buf(gi_writer *w, const char id[4], uint32_t flags, gi_buf *buf,
                      gi_status *st)
{
    if (!gi_buf_ok(buf)) {
        gi_buf_release(buf);
        return gi_status_set(st, GI_EXIT_SYSTEM, "writer: section '%.4s': out of memory", id);
    }
    unsigned char *data = buf->data;
    size_t size = buf->len;
    if (size == 0) {
        free(data);
        data = NULL;
    }
    gi_buf_init(buf);
    return writer_append(w, id, flags, data, size, st);
}

/* Header and section table (plus zero padding up to the first section) in
 * their final bytes; offsets follow the canonical layout. */
static int writer_layout(const gi_writer *w, gi_buf *head, gi_status *st)
{
    uint64_t table_end = HDR + (uint64_t)ENT * w->n;
    uint64_t off = align_up(table_end), end = table_end;
    gi_buf_put_bytes(head, w->magic, 8);
    gi_buf_put_u16(head, w->major);
    gi_buf_put_u16(head, w->minor);
    gi_buf_put_u32(head, (uint32_t)w->n);
    gi_buf_put_u64(head, 0); /* file size, patched below */
    gi_buf_put_u32(head, w->flags);
    gi_buf_put_u32(head, 0); /* header CRC, patched below */
    for (size_t i = 0; i < w->n; i++) {
        const wsection *s = &w->sec[i];
        gi_buf_put_bytes(head, s->id, 4);
        gi_buf_put_u32(head, s->flags);
        gi_buf_put_u64(head, off);
        gi_buf_put_u64(head, s->size);
        gi_buf_put_u32(head, s->crc);
        gi_buf_put_u32(head, 0); /* reserved */
        end = off + s->size;
        off = align_up(end);
    }
    if (w->n > 0)
        gi_buf_put_zeros(head, (size_t)(align_up(table_end) - table_end));
    if (!gi_buf_ok(head))
        return gi_status_set(st, GI_EXIT_SYSTEM, "writer: out of memory");
    gi_buf_set_u64(head, 16, end);
    uint32_t crc = gi_crc32(head->data, 28);
    crc = gi_crc32_update(crc, head->data + HDR, (size_t)(table_end - HDR));
    gi_buf_set_u32(head, 28, crc);
    return 0;
}

static int write_all(FILE *f, const void *p, size_t n)
{
    return n == 0 || fwrite(p, 1, n, f) == n ? 0 : -1;
}

int gi_writer_write(gi_writer *w, const char *path, gi_status *st)
{
    char tmp[TEMP_PATH_MAX + 64];
    if (gi_container_temp_path(path, tmp, sizeof tmp) != 0)
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: path too long", path);
    gi_buf head;
    gi_buf_init(&head);
    int rc = writer_layout(w, &head, st);
    if (rc)
        return rc;

    int handle = gi_container_temp_register(tmp);
    int fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0 && errno == EEXIST) { /* left by a crashed run with the same pid */
        unlink(tmp);
        fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    }
    if (fd < 0) {
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot create temporary file", tmp);
        gi_container_temp_unregister(handle);
        gi_buf_release(&head);
        return rc;
    }
    FILE *f = fdopen(fd, "wb");
    if (!f) {
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s", tmp);
        close(fd);
        goto fail;
    }
    if (write_all(f, head.data, head.len) != 0)
        goto write_error;
    for (size_t i = 0; i < w->n; i++) {
        const wsection *s = &w->sec[i];
        if (write_all(f, s->data, s->size) != 0)
            goto write_error;
        if (i + 1 < w->n && write_all(f, g_zeros, (size_t)(align_up(s->size) - s->size)) != 0)
            goto write_error;
    }
    if (fflush(f) != 0)
        goto write_error;
    if (fsync(fileno(f)) != 0) {
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: fsync", tmp);
        fclose(f);
        goto fail;
    }
    if (fclose(f) != 0) {
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: close", tmp);
        goto fail;
    }
    if (rename(tmp, path) != 0) {
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot rename %s into place", path, tmp);
        goto fail;
    }
    gi_container_temp_unregister(handle);
    gi_buf_release(&head);
    /* Make the rename itself durable; best effort (not all filesystems allow it). */
    {
        char dir[TEMP_PATH_MAX];
        const char *slash = strrchr(path, '/');
        size_t dn = slash ? (size_t)(slash - path) : 0;
        if (!slash)
            strcpy(dir, ".");
        else if (dn == 0)
            strcpy(dir, "/");
        else if (dn < sizeof dir) {
            memcpy(dir, path, dn);
            dir[dn] = '\0';
        } else
            dir[0] = '\0';
        if (dir[0]) {
            int dfd = open(dir, O_RDONLY | O_CLOEXEC);
            if (dfd >= 0) {
                (void)fsync(dfd);
                close(dfd);
            }
        }
    }
    return 0;

write_error:
    rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: write error", tmp);
    fclose(f);
fail:
    unlink(tmp);
    gi_container_temp_unregister(handle);
    gi_buf_release(&head);
    return rc;
}

/* ===== reader ============================================================== */

typedef struct meta_kv {
    const char *key;
    const char *value;
    uint64_t offset; /* of the line in the file, for messages */
} meta_kv;

struct gi_reader {
    char *name;
    const unsigned char *data;
    size_t size;
    void *map; /* mmap'd file, or NULL */
    size_t map_len;
    unsigned char *owned; /* malloc'd copy, or NULL */
    uint16_t major, minor;
    uint32_t flags;
    uint32_t nsec;
    gi_section_info *sec;
    int has_meta;
    char *meta_text;
    meta_kv *meta;
    size_t nmeta;
};

void gi_reader_free(gi_reader *r)
{
    if (!r)
        return;
    if (r->map)
        munmap(r->map, r->map_len);
    free(r->owned);
    free(r->sec);
    free(r->meta_text);
    free(r->meta);
    free(r->name);
    free(r);
}

/* Printable form of n bytes for messages: 'GIPHOTON', 'GIHVDS\x00\x00'. */
static void quote_bytes(const unsigned char *p, size_t n, char *out, size_t cap)
{
    size_t k = 0;
    for (size_t i = 0; i < n && k + 5 < cap; i++) {
        if (p[i] >= 0x20 && p[i] < 0x7f && p[i] != '\\' && p[i] != '\'')
            out[k++] = (char)p[i];
        else
            k += (size_t)snprintf(out + k, cap - k, "\\x%02x", p[i]);
    }
    out[k] = '\0';
}

typedef struct known_magic {
    const char *bytes;
    size_t n;
    const char *what;
} known_magic;

/* Files a gi tool may be handed by mistake, to say what was given. */
static const known_magic g_known[] = {
    {"GIPHOTON", 8, "a .gip file (gi-precompute)"},
    {"GIHVDS\0\0", 8, "a .gih file (gi-hvds)"},
    {"glTF", 4, "a binary glTF (.glb) file"},
    {"\x89PNG\r\n\x1a\n", 8, "a PNG image"},
    {"\x76\x2f\x31\x01", 4, "an OpenEXR image"},
    {"#?RADIANCE", 10, "a Radiance HDR image"},
    {"#?RGBE", 6, "a Radiance HDR image"},
    {"\x1f\x8b", 2, "a gzip file"},
};

static const char *describe_magic(const unsigned char *p, size_t n)
{
    for (size_t i = 0; i < sizeof g_known / sizeof g_known[0]; i++)
        if (n >= g_known[i].n && memcmp(p, g_known[i].bytes, g_known[i].n) == 0)
            return g_known[i].what;
    size_t i = 0;
    while (i < n && (p[i] == ' ' || p[i] == '\t' || p[i] == '\r' || p[i] == '\n'))
        i++;
    if (i < n && p[i] == '{')
        return "a JSON text file (.gltf?)";
    return NULL;
}

static int magic_error(const char *name, const unsigned char *d, size_t n, const char magic[8],
                       gi_status *st)
{
    char want_q[64], got_q[64], want[128];
    quote_bytes((const unsigned char *)magic, 8, want_q, sizeof want_q);
    const char *want_what = describe_magic((const unsigned char *)magic, 8);
    if (want_what)
        snprintf(want, sizeof want, "%s", want_what);
    else
        snprintf(want, sizeof want, "a gi file with magic '%s'", want_q);
    if (n == 0)
        return gi_status_set(st, GI_EXIT_DATA, "%s: empty file, expected %s", name, want);
    if (n < 8 && memcmp(d, magic, n) == 0)
        return gi_status_set(st, GI_EXIT_DATA,
                             "%s: truncated: %zu bytes, shorter than the %d-byte header", name, n,
                             HDR);
    const char *got_what = describe_magic(d, n);
    if (got_what)
        return gi_status_set(st, GI_EXIT_DATA, "%s: is %s, expected %s", name, got_what, want);
    quote_bytes(d, n < 8 ? n : 8, got_q, sizeof got_q);
    return gi_status_set(st, GI_EXIT_DATA, "%s: not %s: starts with '%s', expected '%s'", name,
                         want, got_q, want_q);
}

static int nonzero_gap(const gi_reader *r, uint64_t from, uint64_t to, const char *where,
                       gi_status *st)
{
    for (uint64_t i = from; i < to; i++)
        if (r->data[i] != 0)
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (%s): padding byte 0x%02x is not zero",
                                 r->name, i, where, r->data[i]);
    return 0;
}

typedef struct id_index {
    uint32_t id;
    uint32_t index;
} id_index;

static int cmp_id_index(const void *a, const void *b)
{
    const id_index *x = a, *y = b;
    if (x->id != y->id)
        return x->id < y->id ? -1 : 1;
    return x->index < y->index ? -1 : (x->index > y->index);
}

static int cmp_meta(const void *a, const void *b)
{
    return strcmp(((const meta_kv *)a)->key, ((const meta_kv *)b)->key);
}

/* Split META into sorted key/value pairs; every line must be key=value\n. */
static int parse_meta(gi_reader *r, const gi_section_info *s, gi_status *st)
{
    size_t n = (size_t)s->size;
    const unsigned char *p = r->data + s->offset;
    r->has_meta = 1;
    r->meta_text = malloc(n + 1);
    if (!r->meta_text)
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: section 'META': out of memory", r->name);
    memcpy(r->meta_text, p, n);
    r->meta_text[n] = '\0';
    size_t lines = 0;
    for (size_t i = 0; i < n; i++)
        lines += p[i] == '\n';
    if (lines > 0) {
        r->meta = malloc(lines * sizeof *r->meta);
        if (!r->meta)
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: section 'META': out of memory",
                                 r->name);
    }
    size_t pos = 0, line = 0;
    while (pos < n) {
        uint64_t at = s->offset + pos;
        line++;
        const unsigned char *nl = memchr(p + pos, '\n', n - pos);
        if (!nl)
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (section 'META'): line %zu: "
                                 "no newline at the end of the text",
                                 r->name, at, line);
        size_t le = (size_t)(nl - p);
        if (memchr(p + pos, '\0', le - pos))
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (section 'META'): line %zu: NUL byte",
                                 r->name, at, line);
        const unsigned char *eq = memchr(p + pos, '=', le - pos);
        if (!eq)
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (section 'META'): line %zu: "
                                 "missing '=' (lines are key=value)",
                                 r->name, at, line);
        size_t klen = (size_t)(eq - (p + pos));
        if (!meta_key_valid((const char *)p + pos, klen))
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (section 'META'): line %zu: key is not "
                                 "1-127 characters of A-Z a-z 0-9 . _ -",
                                 r->name, at, line);
        char *t = r->meta_text;
        t[pos + klen] = '\0';
        t[le] = '\0';
        r->meta[r->nmeta].key = t + pos;
        r->meta[r->nmeta].value = t + pos + klen + 1;
        r->meta[r->nmeta].offset = at;
        r->nmeta++;
        pos = le + 1;
    }
    if (r->nmeta > 1)
        qsort(r->meta, r->nmeta, sizeof *r->meta, cmp_meta);
    for (size_t i = 1; i < r->nmeta; i++)
        if (strcmp(r->meta[i - 1].key, r->meta[i].key) == 0)
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (section 'META'): key '%s' appears twice",
                                 r->name, r->meta[i].offset > r->meta[i - 1].offset
                                              ? r->meta[i].offset : r->meta[i - 1].offset,
                                 r->meta[i].key);
    return 0;
}

/* Every check of docs/formats.md "Reader checks", in that order. */
static int validate(gi_reader *r, const char magic[8], uint16_t want_major, gi_status *st)
{
    const unsigned char *d = r->data;
    size_t n = r->size;
    const char *nm = r->name;

    if (n < 8 || memcmp(d, magic, 8) != 0)
        return magic_error(nm, d, n, magic, st);
    if (n < HDR)
        return gi_status_set(st, GI_EXIT_DATA,
                             "%s: truncated: %zu bytes, shorter than the %d-byte header", nm, n,
                             HDR);
    r->major = gi_le_get_u16(d + 8);
    r->minor = gi_le_get_u16(d + 10);
    if (r->major != want_major)
        return gi_status_set(st, GI_EXIT_DATA,
                             "%s: file was written by format %u.%u; this gi reads %u.x (%s)", nm,
                             (unsigned)r->major, (unsigned)r->minor, (unsigned)want_major,
                             r->major > want_major ? "a newer gi wrote it"
                                                   : "re-create it with this gi");
    uint32_t count = gi_le_get_u32(d + 12);
    uint64_t file_size = gi_le_get_u64(d + 16);
    r->flags = gi_le_get_u32(d + 24);
    if (file_size > n)
        return gi_status_set(st, GI_EXIT_DATA,
                             "%s: truncated: the header gives %" PRIu64 " bytes, the file has %zu",
                             nm, file_size, n);
    if (file_size < n)
        return gi_status_set(st, GI_EXIT_DATA,
                             "%s: offset %" PRIu64 ": %" PRIu64 " bytes of trailing data "
                             "(the header gives %" PRIu64 " bytes, the file has %zu)",
                             nm, file_size, (uint64_t)n - file_size, file_size, n);
    if (count > (n - HDR) / ENT)
        return gi_status_set(st, GI_EXIT_DATA,
                             "%s: offset 12: section count %" PRIu32
                             " does not fit in a %zu-byte file",
                             nm, count, n);
    uint64_t table_end = HDR + (uint64_t)ENT * count;
    uint32_t stored = gi_le_get_u32(d + 28);
    uint32_t crc = gi_crc32_update(gi_crc32(d, 28), d + HDR, (size_t)(table_end - HDR));
    if (crc != stored)
        return gi_status_set(st, GI_EXIT_DATA,
                             "%s: offset 28: header checksum mismatch (header and section "
                             "table; stored 0x%08" PRIx32 ", computed 0x%08" PRIx32 ")",
                             nm, stored, crc);

    if (count > 0) {
        r->sec = calloc(count, sizeof *r->sec);
        if (!r->sec)
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", nm);
    }
    r->nsec = count;
    uint64_t prev_end = table_end;
    for (uint32_t i = 0; i < count; i++) {
        const unsigned char *e = d + HDR + (size_t)ENT * i;
        uint64_t eo = HDR + (uint64_t)ENT * i;
        gi_section_info *s = &r->sec[i];
        if (!id_valid((const char *)e)) {
            char q[32];
            quote_bytes(e, 4, q, sizeof q);
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 ": section id '%s' is not 4 printable "
                                 "ASCII characters",
                                 nm, eo, q);
        }
        memcpy(s->id, e, 4);
        s->id[4] = '\0';
        s->flags = gi_le_get_u32(e + 4);
        s->offset = gi_le_get_u64(e + 8);
        s->size = gi_le_get_u64(e + 16);
        s->crc = gi_le_get_u32(e + 24);
        if (gi_le_get_u32(e + 28) != 0)
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (section '%s'): reserved field is not zero",
                                 nm, eo + 28, s->id);
        if (s->offset % ALIGN != 0)
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (section '%s'): data offset %" PRIu64
                                 " is not a multiple of %d",
                                 nm, eo + 8, s->id, s->offset, ALIGN);
        if (s->offset < prev_end)
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (section '%s'): data offset %" PRIu64
                                 " overlaps %s, which ends at %" PRIu64,
                                 nm, eo + 8, s->id, s->offset,
                                 i == 0 ? "the section table" : "the previous section", prev_end);
        if (s->offset > n || s->size > n - s->offset)
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (section '%s'): %" PRIu64
                                 " bytes at offset %" PRIu64
                                 " run past the end of the file (%zu bytes)",
                                 nm, eo + 16, s->id, s->size, s->offset, n);
        char where[40];
        snprintf(where, sizeof where, "before section '%s'", s->id);
        int rc = nonzero_gap(r, prev_end, s->offset, where, st);
        if (rc)
            return rc;
        prev_end = s->offset + s->size;
    }
    int rc = nonzero_gap(r, prev_end, n, "after the last section", st);
    if (rc)
        return rc;

    if (count > 1) {
        id_index *ids = malloc(count * sizeof *ids);
        if (!ids)
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", nm);
        for (uint32_t i = 0; i < count; i++) {
            ids[i].id = gi_le_get_u32(r->sec[i].id);
            ids[i].index = i;
        }
        qsort(ids, count, sizeof *ids, cmp_id_index);
        for (uint32_t i = 1; i < count; i++)
            if (ids[i].id == ids[i - 1].id) {
                uint32_t a = ids[i - 1].index, b = ids[i].index;
                free(ids);
                return gi_status_set(st, GI_EXIT_DATA,
                                     "%s: offset %" PRIu64 " (section '%s'): duplicate section "
                                     "id (first at offset %" PRIu64 ")",
                                     nm, HDR + (uint64_t)ENT * b, r->sec[b].id,
                                     HDR + (uint64_t)ENT * a);
            }
        free(ids);
    }

    for (uint32_t i = 0; i < count; i++) {
        const gi_section_info *s = &r->sec[i];
        uint32_t c = gi_crc32(d + s->offset, (size_t)s->size);
        if (c != s->crc)
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: offset %" PRIu64 " (section '%s'): checksum mismatch "
                                 "(stored 0x%08" PRIx32 ", computed 0x%08" PRIx32 ")",
                                 nm, s->offset, s->id, s->crc, c);
    }
    for (uint32_t i = 0; i < count; i++)
        if (memcmp(r->sec[i].id, "META", 4) == 0)
            return parse_meta(r, &r->sec[i], st);
    return 0;
}

static gi_reader *reader_new(const char *name)
{
    gi_reader *r = calloc(1, sizeof *r);
    if (!r)
        return NULL;
    size_t n = strlen(name);
    r->name = malloc(n + 1);
    if (!r->name) {
        free(r);
        return NULL;
    }
    memcpy(r->name, name, n + 1);
    return r;
}

static int reader_finish(gi_reader *r, const char magic[8], uint16_t major, gi_reader **out,
                         gi_status *st)
{
    int rc = validate(r, magic, major, st);
    if (rc) {
        gi_reader_free(r);
        return rc;
    }
    *out = r;
    return 0;
}

int gi_reader_open_memory(const void *data, size_t size, const char *name,
                          const char magic[8], uint16_t supported_major, gi_reader **out,
                          gi_status *st)
{
    *out = NULL;
    gi_reader *r = reader_new(name);
    if (!r)
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", name);
    /* An exact-size copy: sanitizers catch any read past the end. */
    r->owned = malloc(size ? size : 1);
    if (!r->owned) {
        gi_reader_free(r);
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", name);
    }
    if (size)
        memcpy(r->owned, data, size);
    r->data = r->owned;
    r->size = size;
    return reader_finish(r, magic, supported_major, out, st);
}

/* Read everything from fd (for files that cannot be mapped: pipes, /dev/stdin). */
static int read_fd(int fd, gi_reader *r, gi_status *st)
{
    gi_buf b;
    gi_buf_init(&b);
    for (;;) {
        if (gi_buf_reserve(&b, 1 << 16) != 0) {
            gi_buf_release(&b);
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", r->name);
        }
        ssize_t k = read(fd, b.data + b.len, b.cap - b.len);
        if (k < 0 && errno == EINTR)
            continue;
        if (k < 0) {
            int rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: read error", r->name);
            gi_buf_release(&b);
            return rc;
        }
        if (k == 0)
            break;
        b.len += (size_t)k;
    }
    r->owned = b.data;
    r->data = b.data;
    r->size = b.len;
    if (!r->owned) { /* empty input */
        r->owned = malloc(1);
        r->data = r->owned;
    }
    return 0;
}

int gi_reader_open(const char *path, const char magic[8], uint16_t supported_major,
                   gi_reader **out, gi_status *st)
{
    *out = NULL;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s", path);
    struct stat sb;
    if (fstat(fd, &sb) != 0) {
        int rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s", path);
        close(fd);
        return rc;
    }
    if (S_ISDIR(sb.st_mode)) {
        close(fd);
        errno = EISDIR;
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s", path);
    }
    gi_reader *r = reader_new(path);
    if (!r) {
        close(fd);
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path);
    }
    int mapped = 0;
    if (S_ISREG(sb.st_mode) && sb.st_size > 0 && (uint64_t)sb.st_size <= SIZE_MAX) {
        void *m = mmap(NULL, (size_t)sb.st_size, PROT_READ, MAP_PRIVATE, fd, 0);
        if (m != MAP_FAILED) {
            r->map = m;
            r->map_len = (size_t)sb.st_size;
            r->data = m;
            r->size = (size_t)sb.st_size;
            mapped = 1;
        }
    }
    if (!mapped) {
        int rc = read_fd(fd, r, st);
        if (rc) {
            close(fd);
            gi_reader_free(r);
            return rc;
        }
    }
    close(fd);
    return reader_finish(r, magic, supported_major, out, st);
}

const char *gi_reader_name(const gi_reader *r) { return r->name; }
uint16_t gi_reader_major(const gi_reader *r) { return r->major; }
uint16_t gi_reader_minor(const gi_reader *r) { return r->minor; }
uint32_t gi_reader_flags(const gi_reader *r) { return r->flags; }
uint32_t gi_reader_section_count(const gi_reader *r) { return r->nsec; }

int gi_reader_section_info(const gi_reader *r, uint32_t i, gi_section_info *info)
{
    if (i >= r->nsec)
        return -1;
    *info = r->sec[i];
    return 0;
}

static const gi_section_info *find_section(const gi_reader *r, const char id[4])
{
    for (uint32_t i = 0; i < r->nsec; i++)
        if (memcmp(r->sec[i].id, id, 4) == 0)
            return &r->sec[i];
    return NULL;
}

const void *gi_reader_section(const gi_reader *r, const char id[4], size_t *size)
{
    const gi_section_info *s = find_section(r, id);
    if (size)
        *size = s ? (size_t)s->size : 0;
    return s ? r->data + s->offset : NULL;
}

int gi_reader_require(const gi_reader *r, const char id[4], const void **data, size_t *size,
                      gi_status *st)
{
    const void *p = gi_reader_section(r, id, size);
    if (data)
        *data = p;
    if (!p)
        return gi_status_set(st, GI_EXIT_DATA, "%s: section '%.4s' missing", r->name, id);
    return 0;
}

uint64_t gi_reader_fingerprint(const gi_reader *r)
{
    return gi_hash64(r->data, HDR + (size_t)ENT * r->nsec, 0);
}

const char *gi_reader_meta(const gi_reader *r, const char *key)
{
    if (r->nmeta == 0)
        return NULL;
    meta_kv k = {key, NULL, 0};
    const meta_kv *hit = bsearch(&k, r->meta, r->nmeta, sizeof *r->meta, cmp_meta);
    return hit ? hit->value : NULL;
}

int gi_container_check_input(const gi_reader *r, const char *key, const char *expected,
                             gi_status *st)
{
    const char *tool = gi_reader_meta(r, "tool");
    char rerun[160];
    snprintf(rerun, sizeof rerun, "re-run %.120s", tool ? tool : "the tool that wrote it");
    if (!r->has_meta)
        return gi_status_set(st, GI_EXIT_DATA,
                             "%s: section 'META' missing: cannot tell what the file was made "
                             "from (%s)",
                             r->name, rerun);
    const char *got = gi_reader_meta(r, key);
    if (!got)
        return gi_status_set(st, GI_EXIT_DATA, "%s: section 'META': no '%s' recorded (%s)",
                             r->name, key, rerun);
    if (strcmp(got, expected) == 0)
        return 0;
    if (strncmp(key, "input.", 6) == 0 && key[6]) {
        const char *rest = key + 6;
        const char *dot = strrchr(rest, '.');
        if (dot && dot[1]) /* input.<name>.<attribute>, e.g. input.scene.hash */
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s: section 'META': made from %.*s %s %s, but the %.*s given "
                                 "has %s (%s)",
                                 r->name, (int)(dot - rest), rest, dot + 1, got,
                                 (int)(dot - rest), rest, expected, rerun);
        return gi_status_set(st, GI_EXIT_DATA,
                             "%s: section 'META': made from %s '%s', but the %s given is '%s' "
                             "(%s)",
                             r->name, rest, got, rest, expected, rerun);
    }
    return gi_status_set(st, GI_EXIT_DATA,
                         "%s: section 'META': made with %s=%s, but %s=%s is needed (%s)", r->name,
                         key, got, key, expected, rerun);
}

/* ===== cursor ============================================================== */

int gi_reader_cursor(const gi_reader *r, const char id[4], gi_cursor *c, gi_status *st)
{
    memset(c, 0, sizeof *c);
    const gi_section_info *s = find_section(r, id);
    c->name = r->name;
    memcpy(c->id, id, 4);
    c->id[4] = '\0';
    if (!s)
        return gi_status_set(st, GI_EXIT_DATA, "%s: section '%.4s' missing", r->name, id);
    c->base = r->data + s->offset;
    c->size = (size_t)s->size;
    c->file_offset = s->offset;
    return 0;
}

int gi_cursor_fail(const gi_cursor *c, gi_status *st, const char *fmt, ...)
{
    char what[GI_STATUS_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return gi_status_set(st, GI_EXIT_DATA, "%s: offset %" PRIu64 " (section '%s'): %s",
                         c->name ? c->name : "?", c->file_offset + c->pos, c->id, what);
}

size_t gi_cursor_remaining(const gi_cursor *c) { return c->size - c->pos; }

/* Pointer to the next n bytes and advance, or NULL with the status set. */
static const unsigned char *take(gi_cursor *c, size_t n, gi_status *st)
{
    if (n > c->size - c->pos) {
        gi_cursor_fail(c, st, "truncated: need %zu byte%s, %zu left", n, n == 1 ? "" : "s",
                       c->size - c->pos);
        return NULL;
    }
    const unsigned char *p = c->base + c->pos;
    c->pos += n;
    return p;
}

#define CURSOR_GET(name, type, width, getter)                                \
    int gi_cursor_##name(gi_cursor *c, type *v, gi_status *st)               \
    {                                                                        \
        const unsigned char *p = take(c, width, st);                         \
        if (!p) {                                                            \
            *v = 0;                                                          \
            return GI_EXIT_DATA;                                             \
        }                                                                    \
        *v = getter(p);                                                      \
        return 0;                                                            \
    }

CURSOR_GET(u8, uint8_t, 1, gi_le_get_u8)
CURSOR_GET(u16, uint16_t, 2, gi_le_get_u16)
CURSOR_GET(u32, uint32_t, 4, gi_le_get_u32)
CURSOR_GET(u64, uint64_t, 8, gi_le_get_u64)
CURSOR_GET(i32, int32_t, 4, gi_le_get_i32)
CURSOR_GET(i64, int64_t, 8, gi_le_get_i64)
CURSOR_GET(f32, float, 4, gi_le_get_f32)
CURSOR_GET(f64, double, 8, gi_le_get_f64)

int gi_cursor_bytes(gi_cursor *c, const void **p, size_t n, gi_status *st)
{
    const unsigned char *q = take(c, n, st);
    *p = q;
    return q ? 0 : GI_EXIT_DATA;
}

int gi_cursor_skip(gi_cursor *c, size_t n, gi_status *st)
{
    return take(c, n, st) ? 0 : GI_EXIT_DATA;
}

int gi_cursor_check_count(const gi_cursor *c, uint64_t count, size_t elem_size, const char *what,
                          gi_status *st)
{
    size_t left = c->size - c->pos;
    if (elem_size == 0 || count <= left / elem_size)
        return 0;
    return gi_cursor_fail(c, st, "%s %" PRIu64 " x %zu bytes exceeds the %zu bytes left", what,
                          count, elem_size, left);
}

int gi_cursor_end(const gi_cursor *c, gi_status *st)
{
    if (c->pos == c->size)
        return 0;
    return gi_cursor_fail(c, st, "%zu unparsed bytes at the end of the section",
                          c->size - c->pos);
}
