/* fuzz_gltf.c - libFuzzer harness for the glTF loader: the input is a .gltf
 * (JSON) or .glb (if it starts with "glTF") loaded from memory with no base
 * directory, so external URIs are refused and nothing touches the disk.
 * Any outcome is fine except a crash, a sanitizer report, or a broken
 * contract: 0 with a scene, or GI_EXIT_DATA/GI_EXIT_SYSTEM with none and a
 * message naming the input. Seeds: the Embedded and Binary variants in
 * shared/gltf-samples. */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "gi_scene.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static FILE *devnull;
    static int init;
    if (!init) {
        /* keep single inputs from asking for gigabytes of zero-filled accessors */
        gi_scene_set_load_limit((size_t)1 << 20);
        devnull = fopen("/dev/null", "w");
        init = 1;
    }
    gi_scene *s = NULL;
    gi_status st = {0};
    int rc = gi_scene_load_memory(data, size, "fuzz.gltf", NULL, &s, &st);
    if (rc == 0) {
        if (!s)
            __builtin_trap();
        /* touch what later tools read */
        for (size_t t = 0; t < s->num_triangles; t++)
            for (int k = 0; k < 3; k++)
                if (s->indices[3 * t + (size_t)k] >= s->num_vertices ||
                    s->tri_material[t] >= s->num_materials)
                    __builtin_trap();
        for (size_t m = 0; m < s->num_materials; m++) {
            float uv[2] = {0.3f, -7.5f}, rgb[3];
            gi_scene_base_color(s, &s->materials[m], uv, uv, rgb);
        }
        if (devnull)
            gi_scene_print_json(s, devnull);
        gi_scene_free(s);
    } else {
        if (s || st.code != rc || (rc != GI_EXIT_DATA && rc != GI_EXIT_SYSTEM) ||
            strncmp(st.msg, "fuzz.gltf: ", 11) != 0)
            __builtin_trap();
    }
    return 0;
}
