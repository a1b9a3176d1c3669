/* fuzz_container.c - libFuzzer harness for the container reader: arbitrary
 * bytes must give either a validated reader or GI_EXIT_DATA, never a crash.
 *
 * Each input is tried twice: as given, and "repaired" (magic, major version,
 * file size and every CRC that can be computed set right) so that mutations
 * reach the layout, META and cursor code behind the checksums. Accepted files
 * are walked section by section with a gi_cursor, and the reader's promises
 * (bounds, alignment, unique ids) are checked; a broken promise aborts. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gi_container.h"
#include "gi_crc32.h"
#include "gi_le.h"

static const char MAGIC[8] = {'G', 'I', 'P', 'H', 'O', 'T', 'O', 'N'};

static void walk_section(const gi_reader *r, const gi_section_info *info)
{
    gi_status st = {0};
    gi_cursor c;
    if (gi_reader_cursor(r, info->id, &c, &st) != 0)
        abort(); /* every listed section can be opened */
    if (c.size != info->size || c.file_offset != info->offset)
        abort();
    uint64_t first = 0;
    for (unsigned k = 0;; k++) {
        int rc;
        switch (k % 8) {
        case 0: {
            uint8_t v;
            rc = gi_cursor_u8(&c, &v, &st);
            break;
        }
        case 1: {
            uint16_t v;
            rc = gi_cursor_u16(&c, &v, &st);
            break;
        }
        case 2: {
            uint32_t v;
            rc = gi_cursor_u32(&c, &v, &st);
            break;
        }
        case 3: {
            rc = gi_cursor_u64(&c, &first, &st);
            break;
        }
        case 4: {
            float v;
            rc = gi_cursor_f32(&c, &v, &st);
            break;
        }
        case 5: {
            double v;
            rc = gi_cursor_f64(&c, &v, &st);
            break;
        }
        case 6: {
            int32_t v;
            rc = gi_cursor_i32(&c, &v, &st);
            break;
        }
        default: {
            int64_t v;
            rc = gi_cursor_i64(&c, &v, &st);
            break;
        }
        }
        if (rc != 0) {
            if (rc != GI_EXIT_DATA || st.msg[0] == '\0')
                abort();
            break;
        }
    }
    /* A count read from the data, checked before anyone would allocate. */
    if (gi_cursor_check_count(&c, first, 12, "count", &st) == 0 && first * 12 > c.size - c.pos)
        abort();
    const void *p;
    size_t left = gi_cursor_remaining(&c);
    if (gi_cursor_bytes(&c, &p, left, &st) != 0)
        abort();
    if (gi_cursor_end(&c, &st) != 0)
        abort();
    if (left > 0) {
        volatile unsigned char sink = ((const unsigned char *)p)[left - 1];
        (void)sink;
    }
}

static void try_open(const uint8_t *data, size_t size)
{
    gi_status st = {0};
    gi_reader *r = NULL;
    int rc = gi_reader_open_memory(data, size, "fuzz.gip", MAGIC, 1, &r, &st);
    if (rc != 0) {
        /* Bad data is GI_EXIT_DATA with a message; only memory can fail otherwise. */
        if (r != NULL || st.msg[0] == '\0' || (rc != GI_EXIT_DATA && rc != GI_EXIT_SYSTEM))
            abort();
        return;
    }
    uint32_t n = gi_reader_section_count(r);
    uint64_t prev_end = GI_CONTAINER_HEADER_SIZE + (uint64_t)GI_CONTAINER_ENTRY_SIZE * n;
    for (uint32_t i = 0; i < n; i++) {
        gi_section_info info;
        if (gi_reader_section_info(r, i, &info) != 0)
            abort();
        if (info.offset % GI_CONTAINER_ALIGN != 0 || info.offset < prev_end ||
            info.offset > size || info.size > size - info.offset)
            abort();
        prev_end = info.offset + info.size;
        size_t sz = 0;
        const unsigned char *p = gi_reader_section(r, info.id, &sz);
        if (!p || sz != info.size || gi_crc32(p, sz) != info.crc)
            abort(); /* ids are unique, so this is the same section */
        walk_section(r, &info);
    }
    (void)gi_reader_fingerprint(r);
    const char *tool = gi_reader_meta(r, "tool");
    if (tool)
        (void)strlen(tool);
    gi_status st2 = {0};
    rc = gi_container_check_input(r, "input.scene.hash", "0123456789abcdef", &st2);
    if (rc != 0 && (rc != GI_EXIT_DATA || st2.msg[0] == '\0'))
        abort();
    gi_reader_free(r);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    try_open(data, size);
    if (size < GI_CONTAINER_HEADER_SIZE || size > (1u << 20))
        return 0;
    unsigned char *d = malloc(size);
    if (!d)
        return 0;
    memcpy(d, data, size);
    memcpy(d, MAGIC, 8);
    gi_le_put_u16(d + 8, 1);
    gi_le_put_u64(d + 16, size);
    uint32_t count = gi_le_get_u32(d + 12);
    size_t max = (size - GI_CONTAINER_HEADER_SIZE) / GI_CONTAINER_ENTRY_SIZE;
    if (count > max) {
        count = (uint32_t)max;
        gi_le_put_u32(d + 12, count);
    }
    for (uint32_t i = 0; i < count; i++) {
        unsigned char *e = d + GI_CONTAINER_HEADER_SIZE + (size_t)GI_CONTAINER_ENTRY_SIZE * i;
        uint64_t off = gi_le_get_u64(e + 8), sz = gi_le_get_u64(e + 16);
        if (off <= size && sz <= size - off)
            gi_le_put_u32(e + 24, gi_crc32(d + off, (size_t)sz));
    }
    uint32_t crc = gi_crc32_update(gi_crc32(d, 28), d + GI_CONTAINER_HEADER_SIZE,
                                   (size_t)GI_CONTAINER_ENTRY_SIZE * count);
    gi_le_put_u32(d + 28, crc);
    try_open(d, size);
    free(d);
    return 0;
}
