/* gi_script.h - variant scripts: a text file of frames, each inheriting the
 * previous frame's resolution, camera, lights and material overrides and
 * changing only what it names (grammar and semantics in docs/script.md).
 *
 * Call order:
 *   gi_script_parse_file() or gi_script_parse_string()  -> one owner
 *   gi_script_check(script, scene)        refuse a script that names materials,
 *                                         cameras or lights the scene lacks,
 *                                         before any rendering
 *   gi_script_frame(script, scene, i, &frame) ... gi_frame_release(&frame)
 *   gi_script_free()
 * The parser needs no scene: it checks syntax, numbers, ranges and
 * self-consistency (unique frame names, inner <= outer, nonzero directions).
 * gi_script_check is the separate pass against a scene.
 *
 * Errors: every parse and check error returns GI_EXIT_DATA with a message
 * "file:line:column: expected ..., got '...'" (line and column 1-based, the
 * column in bytes of the offending token). An unreadable file gives
 * GI_EXIT_SYSTEM, out of memory GI_EXIT_SYSTEM, a frame index out of range
 * GI_EXIT_USAGE. Nothing is printed.
 *
 * Ownership: the script is immutable after parsing, so several threads may
 * call gi_script_frame on it at once. A gi_frame owns its arrays; release it
 * with gi_frame_release (a zeroed gi_frame is safe to release). */
#ifndef GI_SCRIPT_H
#define GI_SCRIPT_H

#include <stddef.h>

#include "gi_scene.h"
#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

#define GI_SCRIPT_DEFAULT_WIDTH 640
#define GI_SCRIPT_DEFAULT_HEIGHT 480
#define GI_SCRIPT_MAX_RESOLUTION 16384

typedef struct gi_script gi_script; /* parsed commands, opaque */

/* What changed relative to the previous frame (frame 0: everything). */
enum {
    GI_CHANGED_CAMERA = 1,
    GI_CHANGED_LIGHTS = 2,
    GI_CHANGED_MATERIALS = 4,
    GI_CHANGED_RESOLUTION = 8,
    GI_CHANGED_ALL = 15
};

/* The full state of one frame, resolved against a scene. */
typedef struct gi_frame {
    char name[GI_NAME_MAX];   /* frame name from the script ("scene" without a script) */
    size_t index;             /* 0-based frame index */
    int width, height;        /* pixels */
    int has_camera;           /* 0: the frame has no camera and cannot be rendered */
    gi_camera camera;         /* forward/up orthonormal, yfov in radians */
    size_t num_lights;
    gi_light *lights;         /* glTF lights first (scene order, replaced in place by a
                                 script light of the same name), then lights only the
                                 script defines (order of first mention); switched-off
                                 lights are present with enabled = 0 */
    unsigned char *light_changed;    /* num_lights flags: 1 if the light is new or differs
                                        in effect from the previous frame */
    size_t num_materials;
    gi_material *materials;          /* copy of scene->materials with the script's overrides,
                                        same order and count as the scene */
    unsigned char *material_changed; /* num_materials flags relative to the previous frame */
    unsigned changed;                /* GI_CHANGED_* relative to the previous frame */
} gi_frame;

/* Parse a script file. `path` is used in messages as given. */
int gi_script_parse_file(const char *path, gi_script **out, gi_status *st);
/* Parse `len` bytes of text; `name` (e.g. the file name) prefixes messages. */
int gi_script_parse_string(const char *text, size_t len, const char *name, gi_script **out,
                           gi_status *st);
/* Release a script (NULL is fine). */
void gi_script_free(gi_script *s);

/* Number of frames (at least 1 in a parsed script). */
size_t gi_script_num_frames(const gi_script *s);
/* Name of frame i, or NULL if i is out of range. Borrowed from the script. */
const char *gi_script_frame_name(const gi_script *s, size_t i);
/* Frame by name, or by 0-based decimal index ("3"); -1 if none. Frame names
 * never consist of digits only, so the two cannot be confused. */
int gi_script_find_frame(const gi_script *s, const char *name_or_index);

/* Validate against a scene, in script order: unknown material names, `camera
 * gltf N` with N out of range, `light X on|off` naming a light neither in the
 * scene nor defined earlier in the script. Reports the first problem as
 * file:line:column; GI_EXIT_DATA. */
int gi_script_check(const gi_script *s, const gi_scene *scene, gi_status *st);

/* Resolve the full state at frame i (0-based) against the scene, with the
 * change flags relative to frame i-1. Cost is bounded by the scene's lights
 * and materials plus a short replay, not by i. Out must be zeroed or released;
 * it is zeroed on error. Run gi_script_check first: this reports only what
 * it cannot resolve (a camera index out of range, a name the scene lacks). */
int gi_script_frame(const gi_script *s, const gi_scene *scene, size_t i, gi_frame *out,
                    gi_status *st);
/* State without any script: the scene's lights and materials, camera 0 if any,
 * width 640 and height 480, or 640/aspect if the camera has an aspect ratio.
 * All change flags are set. */
int gi_frame_from_scene(const gi_scene *scene, gi_frame *out, gi_status *st);
/* Free a frame's arrays and zero it (a zeroed frame is fine). */
void gi_frame_release(gi_frame *f);

#ifdef __cplusplus
}
#endif
#endif
