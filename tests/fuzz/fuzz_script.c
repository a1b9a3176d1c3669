/* fuzz_script.c - libFuzzer harness for the variant script parser: parse the
 * input, check it against a small built-in scene, resolve every frame and
 * check the invariants the renderer relies on (unit directions, cones in
 * range, a message with file:line:column on every error). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gi_script.h"

static gi_material g_mats[3];
static gi_light g_lights[3];
static gi_camera g_cams[1];
static gi_scene g_scene;

static void build_scene(void)
{
    static const char *mats[3] = {"LeftWall", "Floor", "Left Wall"};
    for (int k = 0; k < 3; k++) {
        gi_material *m = &g_mats[k];
        memset(m, 0, sizeof *m);
        strcpy(m->name, mats[k]);
        m->base_color[0] = m->base_color[1] = m->base_color[2] = 0.5f;
        m->base_color_tex = -1;
        m->roughness = 1.0f;
    }
    static const char *lights[3] = {"key", "fill", "key"}; /* a duplicate name on purpose */
    for (int k = 0; k < 3; k++) {
        gi_light *l = &g_lights[k];
        memset(l, 0, sizeof *l);
        strcpy(l->name, lights[k]);
        l->type = k == 1 ? GI_LIGHT_SPOT : GI_LIGHT_POINT;
        l->enabled = 1;
        l->color[0] = l->color[1] = l->color[2] = 1.0f;
        l->intensity = 10.0f;
        l->direction[1] = -1.0f;
        l->outer_cone = 0.5f;
    }
    memset(g_cams, 0, sizeof g_cams);
    strcpy(g_cams[0].name, "cam");
    g_cams[0].forward[2] = -1.0f;
    g_cams[0].up[1] = 1.0f;
    g_cams[0].yfov = 0.8f;
    g_cams[0].aspect = 1.25f;
    strcpy(g_scene.path, "fuzz.gltf");
    g_scene.num_materials = 3;
    g_scene.materials = g_mats;
    g_scene.num_lights = 3;
    g_scene.lights = g_lights;
    g_scene.num_cameras = 1;
    g_scene.cameras = g_cams;
}

static void require(int ok)
{
    if (!ok)
        abort();
}

static int is_unit(const float *v) { return fabsf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] - 1.0f) < 1e-4f; }

static void check_frame(const gi_frame *f, size_t i)
{
    require(f->index == i);
    require(f->width >= 1 && f->width <= GI_SCRIPT_MAX_RESOLUTION);
    require(f->height >= 1 && f->height <= GI_SCRIPT_MAX_RESOLUTION);
    require(f->num_materials == g_scene.num_materials);
    require(f->num_lights >= g_scene.num_lights);
    if (f->has_camera) {
        require(is_unit(f->camera.forward) && is_unit(f->camera.up));
        float d = f->camera.forward[0] * f->camera.up[0] + f->camera.forward[1] * f->camera.up[1] +
                  f->camera.forward[2] * f->camera.up[2];
        require(fabsf(d) < 1e-4f);
        require(f->camera.yfov > 0.0f && f->camera.yfov < 3.1416f);
    }
    for (size_t j = 0; j < f->num_lights; j++) {
        const gi_light *l = &f->lights[j];
        require(l->type >= GI_LIGHT_POINT && l->type <= GI_LIGHT_AREA);
        require(isfinite(l->intensity) && l->intensity >= 0.0f);
        if (l->type == GI_LIGHT_SPOT || l->type == GI_LIGHT_DIRECTIONAL || l->type == GI_LIGHT_AREA)
            require(is_unit(l->direction));
        if (l->type == GI_LIGHT_SPOT)
            require(l->inner_cone >= 0.0f && l->inner_cone <= l->outer_cone && l->outer_cone <= 1.5708f);
        (void)f->light_changed[j];
    }
    for (size_t k = 0; k < f->num_materials; k++) {
        const gi_material *m = &f->materials[k];
        require(m->roughness >= 0.0f && m->roughness <= 1.0f);
        (void)f->material_changed[k];
    }
    if (i == 0)
        require(f->changed == GI_CHANGED_ALL);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (!g_scene.materials)
        build_scene();
    gi_script *s = NULL;
    gi_status st = {0};
    int rc = gi_script_parse_string((const char *)data, size, "fuzz.script", &s, &st);
    if (rc) {
        require(rc == GI_EXIT_DATA && s == NULL);
        require(strncmp(st.msg, "fuzz.script:", 12) == 0);
        return 0;
    }
    size_t n = gi_script_num_frames(s);
    require(n >= 1);
    gi_status cst = {0};
    int checked = gi_script_check(s, &g_scene, &cst);
    require(checked == 0 || (checked == GI_EXIT_DATA && strncmp(cst.msg, "fuzz.script:", 12) == 0));
    for (size_t i = 0; i < n; i++) {
        const char *name = gi_script_frame_name(s, i);
        require(name && gi_script_find_frame(s, name) == (int)i);
        gi_frame f = {0};
        rc = gi_script_frame(s, &g_scene, i, &f, &st);
        if (rc == 0)
            check_frame(&f, i);
        else
            require(rc == GI_EXIT_DATA && checked != 0 && f.lights == NULL);
        gi_frame_release(&f);
    }
    gi_frame f = {0};
    require(gi_script_frame(s, &g_scene, n, &f, &st) == GI_EXIT_USAGE);
    require(gi_frame_from_scene(&g_scene, &f, &st) == 0);
    gi_frame_release(&f);
    gi_script_free(s);
    return 0;
}
