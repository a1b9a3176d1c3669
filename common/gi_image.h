/* gi_image.h - float images in memory, read and written through OpenImageIO.
 *
 * A gi_image lives in caller storage: gi_image_init (or gi_image_read) fills it,
 * gi_image_release frees its pixels; a zeroed gi_image is safe to release.
 * Pixels are float, row-major, top row first, channels interleaved
 * (index = (y * width + x) * channels + c). Linear outputs of gi are
 * luminance-scaled radiance in cd/m^2 per RGB channel.
 *
 * Every write goes to "<path>.tmp.<pid>" beside the target, is synced, then
 * renamed over the target; on any failure the temporary file is removed and
 * the target is left untouched. Functions return 0 or a GI_EXIT_* code and fill
 * the caller's gi_status ("file: what: OIIO's message"): GI_EXIT_SYSTEM for a
 * file that cannot be opened, created or renamed (with strerror), for memory,
 * and for encoder failures; GI_EXIT_DATA for a file that exists but is not an
 * image OIIO can decode, or lacks a requested attribute.
 * The implementation is C++ (common/shim/gi_image_oiio.cpp); no C++ exception
 * crosses this API. */
#ifndef GI_IMAGE_H
#define GI_IMAGE_H

#include <stddef.h>

#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_image {
    int width, height, channels;
    float *pixels; /* width * height * channels floats, owned by the struct */
} gi_image;

/* A string attribute stored as "gi:<key>" in an EXR header. */
typedef struct gi_image_meta {
    const char *key;
    const char *value;
} gi_image_meta;

/* Allocate a zero-filled w x h image with 1..4 channels. */
int gi_image_init(gi_image *im, int w, int h, int channels, gi_status *st);
/* Free the pixels and zero the struct; NULL and zeroed structs are fine. */
void gi_image_release(gi_image *im);
/* Read the first subimage of any file OIIO decodes, converted to float.
 * Channel count is kept (1 gray, 2 gray+alpha, 3 RGB, 4 RGBA); channels past
 * the fourth are dropped. Stored values are not altered (alpha is not
 * premultiplied on read); 8-bit files read as byte / 255. *out must be zeroed or released; it is replaced. */
int gi_image_read(const char *path, gi_image *out, gi_status *st);
/* Write 32-bit float OpenEXR, uncompressed (zip saved 8% of float pixels for
 * ~40 ms per 640x480 frame), channel names Y / YA / RGB /
 * RGBA; each meta entry becomes the string attribute "gi:<key>". Empty values
 * are refused (GI_EXIT_DATA): OIIO would drop them silently. */
int gi_image_write_exr(const char *path, const gi_image *im, const gi_image_meta *meta,
                       size_t nmeta, gi_status *st);
/* Copy the string attribute "gi:<key>" of an image file into value (cap bytes,
 * NUL-terminated). GI_EXIT_DATA if absent or longer than cap - 1. */
int gi_image_read_meta(const char *path, const char *key, char *value, size_t cap,
                       gi_status *st);
/* Write an 8-bit PNG with the image's channel count (alpha is stored
 * unassociated, byte for byte). Values are taken as
 * already display-referred: each is clamped to [0,1] and quantised as
 * floor(v * 255 + 0.5); no transfer curve is applied; NaN becomes 0. */
int gi_image_write_png(const char *path, const gi_image *im, gi_status *st);
/* Write an 8-bit RGB PNG of a linear image: v * exposure_scale, clamped to
 * [0,1], sRGB transfer curve (IEC 61966-2-1), floor(s * 255 + 0.5). Gray is
 * replicated to RGB, alpha is dropped; NaN becomes 0. */
int gi_image_write_png_srgb(const char *path, const gi_image *linear, float exposure_scale,
                            gi_status *st);
/* The sRGB transfer curve (linear [0,1] -> encoded [0,1]) used above. */
float gi_image_srgb_encode(float linear);

#ifdef __cplusplus
}
#endif
#endif
