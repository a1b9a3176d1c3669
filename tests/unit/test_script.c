/* test_script.c - variant script parser: values and units, inheritance,
 * light replacement and on/off, change flags, error messages with exact
 * line:column, scene checks, frame lookup and a 10k-frame script.
 * The scene is built by hand (no glTF loader). */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include "gi_script.h"

#define DEG (3.14159265358979323846 / 180.0)

/* ---- a small hand-made scene ------------------------------------------------ */

enum { MAT_LEFT, MAT_RIGHT, MAT_FLOOR, MAT_SPACE, NUM_MATS };
enum { LIGHT_KEY, LIGHT_FILL, NUM_LIGHTS };

static gi_material g_mats[NUM_MATS];
static gi_light g_lights[3];
static gi_camera g_cams[2];
static gi_scene g_scene;

static void set3(float *d, float a, float b, float c)
{
    d[0] = a;
    d[1] = b;
    d[2] = c;
}

static void make_material(gi_material *m, const char *name, float gray, float rough)
{
    memset(m, 0, sizeof *m);
    snprintf(m->name, sizeof m->name, "%s", name);
    set3(m->base_color, gray, gray, gray);
    m->base_color_tex = -1;
    m->uv_xform[0] = m->uv_xform[4] = 1.0f;
    m->roughness = rough;
}

static const gi_scene *scene(void)
{
    memset(&g_scene, 0, sizeof g_scene);
    snprintf(g_scene.path, sizeof g_scene.path, "test.gltf");
    make_material(&g_mats[MAT_LEFT], "LeftWall", 0.5f, 0.8f);
    make_material(&g_mats[MAT_RIGHT], "RightWall", 0.6f, 0.7f);
    make_material(&g_mats[MAT_FLOOR], "Floor", 0.7f, 0.9f);
    make_material(&g_mats[MAT_SPACE], "Left Wall", 0.1f, 0.2f);
    memset(g_lights, 0, sizeof g_lights);
    gi_light *k = &g_lights[LIGHT_KEY];
    snprintf(k->name, sizeof k->name, "key");
    k->type = GI_LIGHT_POINT;
    k->enabled = 1;
    set3(k->color, 1.0f, 0.5f, 0.25f);
    k->intensity = 50.0f;
    set3(k->position, 1, 2, 3);
    gi_light *f = &g_lights[LIGHT_FILL];
    snprintf(f->name, sizeof f->name, "fill");
    f->type = GI_LIGHT_SPOT;
    f->enabled = 1;
    set3(f->color, 0.2f, 0.3f, 0.4f);
    f->intensity = 7.0f;
    set3(f->position, 0, 4, 0);
    set3(f->direction, 0, -1, 0);
    f->inner_cone = 0.1f;
    f->outer_cone = 0.5f;
    f->range = 7.0f;
    memset(g_cams, 0, sizeof g_cams);
    snprintf(g_cams[0].name, sizeof g_cams[0].name, "cam0");
    set3(g_cams[0].position, 0, 1, 5);
    set3(g_cams[0].forward, 0, 0, -1);
    set3(g_cams[0].up, 0, 1, 0);
    g_cams[0].yfov = 0.7f;
    g_cams[0].aspect = 1.5f;
    g_cams[0].znear = 0.1f;
    g_cams[1] = g_cams[0];
    snprintf(g_cams[1].name, sizeof g_cams[1].name, "cam1");
    set3(g_cams[1].position, 3, 1, 5);
    g_scene.num_materials = NUM_MATS;
    g_scene.materials = g_mats;
    g_scene.num_lights = NUM_LIGHTS;
    g_scene.lights = g_lights;
    g_scene.num_cameras = 2;
    g_scene.cameras = g_cams;
    return &g_scene;
}

/* ---- helpers ------------------------------------------------------------------ */

static gi_script *parse_ok(const char *text)
{
    gi_script *s = NULL;
    gi_status st = {0};
    int rc = gi_script_parse_string(text, strlen(text), "variants.script", &s, &st);
    if (rc)
        print_error("unexpected parse error: %s\n", st.msg);
    assert_int_equal(rc, 0);
    assert_non_null(s);
    return s;
}

static void frame_ok(const gi_script *s, size_t i, gi_frame *f)
{
    gi_status st = {0};
    int rc = gi_script_frame(s, scene(), i, f, &st);
    if (rc)
        print_error("unexpected frame error: %s\n", st.msg);
    assert_int_equal(rc, 0);
}

static void expect_parse_error(const char *text, const char *msg)
{
    gi_script *s = NULL;
    gi_status st = {0};
    int rc = gi_script_parse_string(text, strlen(text), "variants.script", &s, &st);
    if (rc != GI_EXIT_DATA || strcmp(st.msg, msg) != 0)
        print_error("input:\n%s\nexpected: %s\ngot (rc %d): %s\n", text, msg, rc, st.msg);
    assert_int_equal(rc, GI_EXIT_DATA);
    assert_null(s);
    assert_string_equal(st.msg, msg);
}

static void expect_check_error(const char *text, const char *msg)
{
    gi_script *s = parse_ok(text);
    gi_status st = {0};
    int rc = gi_script_check(s, scene(), &st);
    if (rc != GI_EXIT_DATA || strcmp(st.msg, msg) != 0)
        print_error("input:\n%s\nexpected: %s\ngot (rc %d): %s\n", text, msg, rc, st.msg);
    assert_int_equal(rc, GI_EXIT_DATA);
    assert_string_equal(st.msg, msg);
    gi_script_free(s);
}

static const gi_light *find_light(const gi_frame *f, const char *name, size_t *idx)
{
    for (size_t j = 0; j < f->num_lights; j++)
        if (strcmp(f->lights[j].name, name) == 0) {
            if (idx)
                *idx = j;
            return &f->lights[j];
        }
    fail_msg("light '%s' not in frame '%s'", name, f->name);
    return NULL;
}

static double dot3(const float *a, const float *b) { return (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2]; }

#define assert_vec(v, x, y, z, eps) assert_vec_at((v), (x), (y), (z), (eps), __LINE__)
static void assert_vec_at(const float *v, double x, double y, double z, double eps, int line)
{
    if (!(fabs(v[0] - x) <= eps && fabs(v[1] - y) <= eps && fabs(v[2] - z) <= eps))
        fail_msg("line %d: got (%.9g %.9g %.9g), expected (%.9g %.9g %.9g) within %g", line, v[0], v[1],
                 v[2], x, y, z, eps);
}

/* ---- the exact syntax of the specification -------------------------------------- */

static const char *k_issue_text =
    "resolution 640 480\n"
    "camera position 2.78 2.73 -8.0 target 2.78 2.73 0 up 0 1 0 fov 39.3     # fov = vertical, degrees\n"
    "camera gltf 0                          # camera index 0 of the glTF scene\n"
    "light key point position 2.78 5.4 2.79 intensity 100 color 1 1 1            # candela\n"
    "light spot1 spot position 1 2 3 direction 0 -1 0 intensity 500 inner 20 outer 30   # cone half-angles, degrees\n"
    "light sun directional direction -0.3 -1 -0.2 illuminance 10000             # lux\n"
    "light panel area center 2.78 5.48 2.79 u 0.65 0 0 v 0 0 0.525 luminance 1000 # nits; u,v half edges, emits along u x v\n"
    "light key off        # switch off (a glTF light by name too); `light key on` switches back on\n"
    "material LeftWall basecolor 0.63 0.065 0.05 roughness 1 metallic 0   # any subset of the properties; also `emission r g b` (nits)\n"
    "frame name-of-frame\n";

static void test_issue_syntax(void **state)
{
    (void)state;
    gi_script *s = parse_ok(k_issue_text);
    gi_status st = {0};
    assert_int_equal(gi_script_check(s, scene(), &st), 0);
    assert_int_equal(gi_script_num_frames(s), 1);
    gi_frame f = {0};
    frame_ok(s, 0, &f);
    assert_string_equal(f.name, "name-of-frame");
    assert_int_equal(f.width, 640);
    assert_int_equal(f.height, 480);
    assert_true(f.has_camera);
    assert_string_equal(f.camera.name, "cam0"); /* camera gltf 0 came last */
    /* key replaces the scene's key in place, then is switched off */
    assert_int_equal(f.num_lights, NUM_LIGHTS + 3);
    size_t ki;
    const gi_light *key = find_light(&f, "key", &ki);
    assert_int_equal(ki, LIGHT_KEY);
    assert_int_equal(key->enabled, 0);
    assert_float_equal(key->intensity, 100.0f, 0);
    assert_vec(key->position, 2.78, 5.4, 2.79, 1e-6);
    assert_vec(key->color, 1, 1, 1, 0);
    const gi_light *sp = find_light(&f, "spot1", NULL);
    assert_int_equal(sp->type, GI_LIGHT_SPOT);
    assert_int_equal(sp->enabled, 1);
    assert_float_equal(sp->intensity, 500.0f, 0);
    assert_float_equal(sp->inner_cone, 20 * DEG, 1e-6);
    assert_float_equal(sp->outer_cone, 30 * DEG, 1e-6);
    assert_vec(sp->direction, 0, -1, 0, 0);
    const gi_light *sun = find_light(&f, "sun", NULL);
    double n = sqrt(0.09 + 1 + 0.04);
    assert_int_equal(sun->type, GI_LIGHT_DIRECTIONAL);
    assert_float_equal(sun->intensity, 10000.0f, 0);
    assert_vec(sun->direction, -0.3 / n, -1 / n, -0.2 / n, 1e-6);
    const gi_light *pa = find_light(&f, "panel", NULL);
    assert_int_equal(pa->type, GI_LIGHT_AREA);
    assert_float_equal(pa->intensity, 1000.0f, 0);
    assert_vec(pa->position, 2.78, 5.48, 2.79, 1e-6);
    assert_vec(pa->u, 0.65, 0, 0, 1e-7);
    assert_vec(pa->v, 0, 0, 0.525, 1e-7);
    assert_vec(pa->direction, 0, -1, 0, 1e-7); /* u x v points down from the ceiling */
    /* order: scene lights, then script lights in order of first mention */
    assert_string_equal(f.lights[2].name, "spot1");
    assert_string_equal(f.lights[3].name, "sun");
    assert_string_equal(f.lights[4].name, "panel");
    const gi_material *lw = &f.materials[MAT_LEFT];
    assert_vec(lw->base_color, 0.63, 0.065, 0.05, 1e-7);
    assert_float_equal(lw->roughness, 1.0f, 0);
    assert_float_equal(lw->metallic, 0.0f, 0);
    assert_vec(f.materials[MAT_RIGHT].base_color, 0.6f, 0.6f, 0.6f, 0); /* untouched */
    assert_int_equal(f.changed, GI_CHANGED_ALL);
    gi_frame_release(&f);
    gi_script_free(s);
}

/* Each line of the specification in a frame of its own, so nothing overrides it. */
static void test_issue_lines_one_by_one(void **state)
{
    (void)state;
    gi_script *s = parse_ok(
        "camera position 2.78 2.73 -8.0 target 2.78 2.73 0 up 0 1 0 fov 39.3     # fov = vertical, degrees\n"
        "frame cam\n"
        "camera gltf 1\n"
        "frame gltfcam\n"
        "light key on\n"
        "material LeftWall emission 10 20 30\n"
        "frame on\n");
    gi_frame f = {0};
    frame_ok(s, 0, &f);
    assert_true(f.has_camera);
    assert_vec(f.camera.position, 2.78, 2.73, -8.0, 1e-6);
    assert_vec(f.camera.forward, 0, 0, 1, 1e-7);
    assert_vec(f.camera.up, 0, 1, 0, 1e-7);
    assert_float_equal(f.camera.yfov, 39.3 * DEG, 1e-6);
    gi_frame_release(&f);
    frame_ok(s, 1, &f);
    assert_string_equal(f.camera.name, "cam1");
    assert_vec(f.camera.position, 3, 1, 5, 0);
    assert_int_equal(f.changed, GI_CHANGED_CAMERA);
    gi_frame_release(&f);
    frame_ok(s, 2, &f);
    assert_int_equal(f.lights[LIGHT_KEY].enabled, 1);
    assert_vec(f.materials[MAT_LEFT].emission, 10, 20, 30, 0);
    assert_vec(f.materials[MAT_LEFT].base_color, 0.5, 0.5, 0.5, 0); /* only emission named */
    assert_int_equal(f.changed, GI_CHANGED_MATERIALS);
    gi_frame_release(&f);
    gi_script_free(s);
}

/* The example at the top of docs/script.md. */
static void test_docs_example(void **state)
{
    (void)state;
    gi_script *s = parse_ok("# variants.script - three variants of the Cornell box\n"
                            "resolution 640 480\n"
                            "camera position 2.78 2.73 -8.0 target 2.78 2.73 0 up 0 1 0 fov 39.3\n"
                            "light panel area center 2.78 5.48 2.79 u 0.65 0 0 v 0 0 0.525 luminance 1000\n"
                            "frame base\n"
                            "\n"
                            "light panel off\n"
                            "light lamp point position 2.78 4.0 2.79 intensity 100 color 1 0.9 0.8\n"
                            "frame lamp                      # the panel stays off, the lamp is added\n"
                            "\n"
                            "material LeftWall basecolor 0.2 0.3 0.63\n"
                            "frame blue-wall                 # same lights as 'lamp', one wall recoloured\n");
    gi_status st = {0};
    assert_int_equal(gi_script_check(s, scene(), &st), 0);
    assert_int_equal(gi_script_num_frames(s), 3);
    gi_frame f = {0};
    frame_ok(s, 2, &f);
    assert_string_equal(f.name, "blue-wall");
    assert_int_equal(find_light(&f, "panel", NULL)->enabled, 0);
    assert_int_equal(find_light(&f, "lamp", NULL)->enabled, 1);
    assert_vec(find_light(&f, "lamp", NULL)->color, 1, 0.9, 0.8, 1e-7);
    assert_vec(f.materials[MAT_LEFT].base_color, 0.2, 0.3, 0.63, 1e-7);
    assert_int_equal(f.changed, GI_CHANGED_MATERIALS);
    gi_frame_release(&f);
    frame_ok(s, 1, &f);
    assert_int_equal(f.changed, GI_CHANGED_LIGHTS);
    assert_int_equal(f.num_lights, NUM_LIGHTS + 2);
    gi_frame_release(&f);
    gi_script_free(s);
}

/* ---- values and units --------------------------------------------------------------- */

static void test_camera_values(void **state)
{
    (void)state;
    gi_script *s = parse_ok("camera position 0 0 0 target 0 0 -2 up 0 1 1\n"
                            "frame tilted\n"
                            "camera direction 1 0 0 position 1 2 3 near 0.5 far 100\n"
                            "frame defaults\n");
    gi_frame f = {0};
    frame_ok(s, 0, &f);
    assert_vec(f.camera.forward, 0, 0, -1, 1e-7);
    /* up 0 1 1 is made orthogonal to the view direction and unit */
    assert_true(fabs(dot3(f.camera.up, f.camera.forward)) < 1e-6);
    assert_float_equal(dot3(f.camera.up, f.camera.up), 1.0, 1e-6);
    assert_vec(f.camera.up, 0, 1, 0, 1e-7);
    assert_float_equal(f.camera.yfov, 45 * DEG, 1e-6); /* default fov */
    gi_frame_release(&f);
    frame_ok(s, 1, &f);
    assert_vec(f.camera.position, 1, 2, 3, 0);
    assert_vec(f.camera.forward, 1, 0, 0, 0);
    assert_vec(f.camera.up, 0, 1, 0, 1e-7);
    assert_float_equal(f.camera.znear, 0.5f, 0);
    assert_float_equal(f.camera.zfar, 100.0f, 0);
    gi_frame_release(&f);
    gi_script_free(s);
}

static void test_light_defaults_and_units(void **state)
{
    (void)state;
    gi_script *s = parse_ok("light a point intensity 5 position 1 1 1   # order is free\n"
                            "light b spot outer 45 direction 0 0 -3 position 0 0 0 intensity 2 color 0.5 1 2\n"
                            "light c spot position 0 0 0 direction 3 4 0 intensity 1 inner 90 outer 90\n"
                            "frame f\n");
    gi_frame f = {0};
    frame_ok(s, 0, &f);
    const gi_light *a = find_light(&f, "a", NULL);
    assert_vec(a->color, 1, 1, 1, 0); /* omitted color is white */
    assert_float_equal(a->intensity, 5.0f, 0);
    assert_int_equal(a->enabled, 1);
    const gi_light *b = find_light(&f, "b", NULL);
    assert_float_equal(b->inner_cone, 0.0f, 0); /* inner defaults to 0 */
    assert_float_equal(b->outer_cone, 45 * DEG, 1e-6);
    assert_vec(b->direction, 0, 0, -1, 0);
    assert_vec(b->color, 0.5, 1, 2, 0);
    const gi_light *c = find_light(&f, "c", NULL);
    assert_vec(c->direction, 0.6, 0.8, 0, 1e-7);
    assert_float_equal(c->inner_cone, c->outer_cone, 0);
    assert_float_equal(c->outer_cone, 90 * DEG, 1e-6);
    gi_frame_release(&f);
    gi_script_free(s);
}

static void test_resolution(void **state)
{
    (void)state;
    gi_script *s = parse_ok("frame a\nresolution 320 200\nframe b\nframe c\nresolution 16384 1\nframe d\n");
    gi_frame f = {0};
    frame_ok(s, 0, &f);
    assert_int_equal(f.width, 640);
    assert_int_equal(f.height, 480);
    assert_false(f.has_camera); /* no camera needed unless rendered */
    gi_frame_release(&f);
    frame_ok(s, 1, &f);
    assert_int_equal(f.width, 320);
    assert_int_equal(f.height, 200);
    assert_int_equal(f.changed, GI_CHANGED_RESOLUTION);
    gi_frame_release(&f);
    frame_ok(s, 2, &f);
    assert_int_equal(f.width, 320);
    assert_int_equal(f.changed, 0);
    gi_frame_release(&f);
    frame_ok(s, 3, &f);
    assert_int_equal(f.width, 16384);
    assert_int_equal(f.height, 1);
    gi_frame_release(&f);
    gi_script_free(s);
}

/* ---- semantics ---------------------------------------------------------------------- */

static void test_inheritance(void **state)
{
    (void)state;
    gi_script *s = parse_ok("light extra point position 0 1 0 intensity 3\n"
                            "material Floor basecolor 0.2 0.3 0.4\n"
                            "camera gltf 0\n"
                            "frame one\n"
                            "camera gltf 1\n"
                            "frame two\n"
                            "material Floor roughness 0.25\n"
                            "frame three\n");
    gi_frame f = {0};
    frame_ok(s, 1, &f);
    assert_string_equal(f.camera.name, "cam1");
    const gi_light *e = find_light(&f, "extra", NULL);
    assert_float_equal(e->intensity, 3.0f, 0);
    assert_vec(f.materials[MAT_FLOOR].base_color, 0.2, 0.3, 0.4, 1e-7);
    gi_frame_release(&f);
    frame_ok(s, 2, &f);
    /* overrides accumulate: basecolor from frame one, roughness from frame three */
    assert_vec(f.materials[MAT_FLOOR].base_color, 0.2, 0.3, 0.4, 1e-7);
    assert_float_equal(f.materials[MAT_FLOOR].roughness, 0.25f, 0);
    assert_string_equal(f.camera.name, "cam1");
    assert_int_equal(f.changed, GI_CHANGED_MATERIALS);
    gi_frame_release(&f);
    gi_script_free(s);
}

static void test_replace_gltf_light(void **state)
{
    (void)state;
    gi_script *s = parse_ok("frame before\n"
                            "light fill point position 0 3 0 intensity 10\n"
                            "frame after\n");
    gi_frame f = {0};
    frame_ok(s, 0, &f);
    assert_int_equal(f.lights[LIGHT_FILL].type, GI_LIGHT_SPOT);
    assert_float_equal(f.lights[LIGHT_FILL].range, 7.0f, 0);
    gi_frame_release(&f);
    frame_ok(s, 1, &f);
    assert_int_equal(f.num_lights, NUM_LIGHTS); /* replaced in place, not added */
    const gi_light *l = &f.lights[LIGHT_FILL];
    assert_string_equal(l->name, "fill");
    assert_int_equal(l->type, GI_LIGHT_POINT);
    assert_vec(l->color, 1, 1, 1, 0); /* wholly replaced: colour not inherited */
    assert_float_equal(l->range, 0.0f, 0);
    assert_float_equal(l->outer_cone, 0.0f, 0);
    assert_int_equal(l->enabled, 1);
    assert_int_equal(f.changed, GI_CHANGED_LIGHTS);
    assert_int_equal(f.light_changed[LIGHT_FILL], 1);
    assert_int_equal(f.light_changed[LIGHT_KEY], 0);
    gi_frame_release(&f);
    gi_script_free(s);
}

static void test_duplicate_scene_light_names(void **state)
{
    (void)state;
    gi_scene sc = *scene();
    gi_light two[2] = {g_lights[LIGHT_KEY], g_lights[LIGHT_KEY]};
    snprintf(two[0].name, sizeof two[0].name, "dup");
    snprintf(two[1].name, sizeof two[1].name, "dup");
    sc.lights = two;
    sc.num_lights = 2;
    gi_script *s = parse_ok("light dup off\nframe a\nlight dup point position 0 0 0 intensity 1\nframe b\n");
    gi_status st = {0};
    gi_frame f = {0};
    assert_int_equal(gi_script_frame(s, &sc, 0, &f, &st), 0);
    assert_int_equal(f.lights[0].enabled, 0);
    assert_int_equal(f.lights[1].enabled, 0);
    gi_frame_release(&f);
    assert_int_equal(gi_script_frame(s, &sc, 1, &f, &st), 0);
    assert_int_equal(f.num_lights, 2);
    assert_int_equal(f.lights[0].enabled, 1);
    assert_float_equal(f.lights[0].intensity, 1.0f, 0);
    assert_int_equal(f.lights[1].enabled, 0); /* one script light replaces both */
    gi_frame_release(&f);
    gi_script_free(s);
}

static void test_off_on(void **state)
{
    (void)state;
    gi_script *s = parse_ok("light key off\n"
                            "light mine point position 0 0 0 intensity 2 color 0 1 0\n"
                            "frame a\n"
                            "light mine off\n"
                            "frame b\n"
                            "light key on\n"
                            "frame c\n"
                            "light mine point position 0 0 0 intensity 2 color 0 1 0\n" /* redefinition: on */
                            "frame d\n"
                            "light mine off\n"
                            "frame e\n"
                            "light mine on\n"
                            "frame f\n");
    gi_status st = {0};
    assert_int_equal(gi_script_check(s, scene(), &st), 0);
    gi_frame f = {0};
    frame_ok(s, 0, &f);
    assert_int_equal(f.lights[LIGHT_KEY].enabled, 0);
    assert_float_equal(f.lights[LIGHT_KEY].intensity, 50.0f, 0); /* the scene's light, just off */
    assert_int_equal(find_light(&f, "mine", NULL)->enabled, 1);
    gi_frame_release(&f);
    frame_ok(s, 1, &f);
    assert_int_equal(f.lights[LIGHT_KEY].enabled, 0);
    assert_int_equal(find_light(&f, "mine", NULL)->enabled, 0);
    assert_int_equal(f.changed, GI_CHANGED_LIGHTS);
    gi_frame_release(&f);
    frame_ok(s, 2, &f);
    assert_int_equal(f.lights[LIGHT_KEY].enabled, 1);
    assert_vec(f.lights[LIGHT_KEY].color, 1, 0.5, 0.25, 0);
    assert_int_equal(find_light(&f, "mine", NULL)->enabled, 0);
    gi_frame_release(&f);
    frame_ok(s, 3, &f);
    assert_int_equal(find_light(&f, "mine", NULL)->enabled, 1);
    gi_frame_release(&f);
    frame_ok(s, 4, &f);
    assert_int_equal(find_light(&f, "mine", NULL)->enabled, 0);
    gi_frame_release(&f);
    frame_ok(s, 5, &f);
    assert_int_equal(find_light(&f, "mine", NULL)->enabled, 1);
    assert_vec(find_light(&f, "mine", NULL)->color, 0, 1, 0, 0);
    gi_frame_release(&f);
    gi_script_free(s);
}

static void test_changed_flags(void **state)
{
    (void)state;
    gi_script *s = parse_ok("light key point position 1 2 3 intensity 50 color 1 0.5 0.25\n" /* 0 */
                            "material RightWall roughness 0.7\n"
                            "frame f0\n"
                            "light key point position 1 2 3 intensity 50 color 1 0.5 0.25\n" /* 1: restated */
                            "material RightWall roughness 0.7 basecolor 0.6 0.6 0.6\n"
                            "resolution 640 480\n"
                            "frame f1\n"
                            "camera gltf 1\n" /* 2 */
                            "frame f2\n"
                            "material RightWall roughness 0.3\n" /* 3 */
                            "frame f3\n"
                            "resolution 100 100\n" /* 4 */
                            "frame f4\n"
                            "light key point position 1 2 3 intensity 60\n" /* 5 */
                            "frame f5\n"
                            "light new directional direction 0 -1 0 illuminance 1\n" /* 6 */
                            "frame f6\n"
                            "light fill off\n" /* 7 */
                            "frame f7\n"
                            "light fill off\n" /* 8: already off */
                            "camera gltf 1\n"
                            "frame f8\n"
                            "light fill spot position 0 4 0 direction 0 -1 0 intensity 99 outer 10\n" /* 9 */
                            "light fill off\n"                                                        /* still dark */
                            "frame f9\n");
    gi_frame f = {0};
    frame_ok(s, 0, &f);
    assert_int_equal(f.changed, GI_CHANGED_ALL);
    for (size_t j = 0; j < f.num_lights; j++)
        assert_int_equal(f.light_changed[j], 1);
    for (size_t k = 0; k < f.num_materials; k++)
        assert_int_equal(f.material_changed[k], 1);
    gi_frame_release(&f);
    static const unsigned expect[] = {GI_CHANGED_ALL, 0, GI_CHANGED_CAMERA, GI_CHANGED_MATERIALS,
                                      GI_CHANGED_RESOLUTION, GI_CHANGED_LIGHTS, GI_CHANGED_LIGHTS,
                                      GI_CHANGED_LIGHTS, 0, 0};
    for (size_t i = 1; i < sizeof expect / sizeof expect[0]; i++) {
        frame_ok(s, i, &f);
        if (f.changed != expect[i])
            print_error("frame %zu: changed %u, expected %u\n", i, f.changed, expect[i]);
        assert_int_equal(f.changed, expect[i]);
        size_t nl = 0, nm = 0;
        for (size_t j = 0; j < f.num_lights; j++)
            nl += f.light_changed[j];
        for (size_t k = 0; k < f.num_materials; k++)
            nm += f.material_changed[k];
        assert_int_equal(nl > 0, (expect[i] & GI_CHANGED_LIGHTS) != 0);
        assert_int_equal(nm > 0, (expect[i] & GI_CHANGED_MATERIALS) != 0);
        if (i == 3) {
            assert_int_equal(nm, 1);
            assert_int_equal(f.material_changed[MAT_RIGHT], 1);
        }
        if (i == 5) {
            assert_int_equal(nl, 1);
            assert_int_equal(f.light_changed[LIGHT_KEY], 1);
        }
        if (i == 6) {
            assert_int_equal(nl, 1);
            assert_int_equal(f.num_lights, NUM_LIGHTS + 1);
            assert_int_equal(f.light_changed[NUM_LIGHTS], 1);
        }
        if (i == 7) {
            assert_int_equal(nl, 1);
            assert_int_equal(f.light_changed[LIGHT_FILL], 1);
        }
        gi_frame_release(&f);
    }
    gi_script_free(s);
}

/* Random access crosses snapshot blocks and must match the sequential meaning. */
static void test_random_access(void **state)
{
    (void)state;
    size_t cap = 1 << 16, n = 0;
    char *text = malloc(cap);
    assert_non_null(text);
    for (int i = 0; i < 200; i++) {
        if (i % 3 == 0)
            n += (size_t)snprintf(text + n, cap - n, "light k point position 0 0 0 intensity %d\n", i);
        if (i % 7 == 0)
            n += (size_t)snprintf(text + n, cap - n, "material Floor roughness %g\n", (i % 10) / 10.0);
        n += (size_t)snprintf(text + n, cap - n, "frame f%d\n", i);
    }
    gi_script *s = parse_ok(text);
    free(text);
    static const size_t order[] = {199, 0, 17, 16, 15, 32, 33, 100, 1, 48, 47};
    for (size_t t = 0; t < sizeof order / sizeof order[0]; t++) {
        size_t i = order[t];
        gi_frame f = {0};
        frame_ok(s, i, &f);
        assert_int_equal(f.index, i);
        char name[16];
        snprintf(name, sizeof name, "f%zu", i);
        assert_string_equal(f.name, name);
        assert_float_equal(find_light(&f, "k", NULL)->intensity, (float)(3 * (i / 3)), 0);
        assert_float_equal(f.materials[MAT_FLOOR].roughness, (float)(((7 * (i / 7)) % 10) / 10.0), 1e-7);
        if (i > 0) {
            unsigned want = (i % 3 == 0 ? GI_CHANGED_LIGHTS : 0u);
            /* a roughness restated with the same value is no change */
            if (i % 7 == 0 && (i % 10) != ((i - 7) % 10))
                want |= GI_CHANGED_MATERIALS;
            assert_int_equal(f.changed, want);
        }
        gi_frame_release(&f);
    }
    gi_script_free(s);
}

/* ---- syntax -------------------------------------------------------------------------- */

static void test_lexical(void **state)
{
    (void)state;
    const char text[] = "\xEF\xBB\xBF# leading comment\r\n"
                        "\r\n"
                        "   \t \n"
                        "material \"Left Wall\" roughness 0.5#comment right after a number\r\n"
                        "light \"say \\\"hi\\\"\" point position 0 0 0 intensity 1\n"
                        "frame first#no space before the comment\r\n"
                        "frame second"; /* no final newline */
    gi_script *s = parse_ok(text);
    assert_int_equal(gi_script_num_frames(s), 2);
    assert_string_equal(gi_script_frame_name(s, 0), "first");
    assert_string_equal(gi_script_frame_name(s, 1), "second");
    assert_null(gi_script_frame_name(s, 2));
    gi_frame f = {0};
    frame_ok(s, 0, &f);
    assert_float_equal(f.materials[MAT_SPACE].roughness, 0.5f, 0);
    assert_float_equal(f.materials[MAT_LEFT].roughness, 0.8f, 0);
    assert_non_null(find_light(&f, "say \"hi\"", NULL));
    gi_frame_release(&f);
    gi_script_free(s);
}

static void test_find_frame(void **state)
{
    (void)state;
    gi_script *s = parse_ok("frame intro\nframe x1\nframe 2b\nframe last.v2\n");
    assert_int_equal(gi_script_find_frame(s, "intro"), 0);
    assert_int_equal(gi_script_find_frame(s, "x1"), 1);
    assert_int_equal(gi_script_find_frame(s, "2b"), 2);
    assert_int_equal(gi_script_find_frame(s, "last.v2"), 3);
    assert_int_equal(gi_script_find_frame(s, "0"), 0);
    assert_int_equal(gi_script_find_frame(s, "3"), 3);
    assert_int_equal(gi_script_find_frame(s, "4"), -1);
    assert_int_equal(gi_script_find_frame(s, "-1"), -1);
    assert_int_equal(gi_script_find_frame(s, ""), -1);
    assert_int_equal(gi_script_find_frame(s, "Intro"), -1);
    assert_int_equal(gi_script_find_frame(s, "99999999999999999999"), -1);
    assert_int_equal(gi_script_find_frame(s, NULL), -1);
    gi_script_free(s);
}

static void test_parse_errors(void **state)
{
    (void)state;
    static const struct {
        const char *text, *msg;
    } cases[] = {
        /* the example of the specification */
        {"resolution 640 480\n# comment\nlight lamp point intensity bright position 0 0 0\nframe a\n",
         "variants.script:3:28: expected a number after 'intensity', got 'bright'"},
        /* missing number at the end of the line: column just after the last token */
        {"light key point position 1 2 3 intensity\nframe a\n",
         "variants.script:1:41: expected a number after 'intensity', got end of line"},
        {"camera position 0 0 target 0 0 1\nframe a\n",
         "variants.script:1:21: expected 3 numbers after 'position', got 'target'"},
        {"light k point position 0 0 0 intensity 1e999\nframe a\n",
         "variants.script:1:40: expected a finite number after 'intensity', got '1e999'"},
        {"camera position 0 0 nan target 0 0 1\nframe a\n",
         "variants.script:1:21: expected a finite number after 'position', got 'nan'"},
        {"light k point position 0 0 0 intensity 1e39\nframe a\n",
         "variants.script:1:40: expected a finite number after 'intensity', got '1e39'"},
        {"light k point position 0 0 0 intensity 12abc\nframe a\n",
         "variants.script:1:40: expected a number after 'intensity', got '12abc'"},
        {"  lamp on\nframe a\n",
         "variants.script:1:3: expected a command (resolution, camera, light, material, frame), got 'lamp'"},
        {"light key laser position 0 0 0\nframe a\n",
         "variants.script:1:11: expected a light type (point, spot, directional, area) or 'on'/'off' "
         "after 'key', got 'laser'"},
        {"light key\nframe a\n",
         "variants.script:1:10: expected a light type (point, spot, directional, area) or 'on'/'off' "
         "after 'key', got end of line"},
        {"light s spot position 0 0 0 direction 0 -1 0 intensity 1 inner 40 outer 30\nframe a\n",
         "variants.script:1:64: expected 'inner' <= 'outer' (30 degrees), got '40'"},
        {"light s spot position 0 0 0 direction 0 -1 0 intensity 1 outer 120\nframe a\n",
         "variants.script:1:64: expected 'outer' greater than 0 and at most 90 degrees, got '120'"},
        {"light s spot position 0 0 0 direction 0 -1 0 intensity 1 inner -1 outer 10\nframe a\n",
         "variants.script:1:64: expected 'inner' in 0..90 degrees, got '-1'"},
        {"light sun directional direction 0 0 0 illuminance 5\nframe a\n",
         "variants.script:1:33: expected a nonzero vector after 'direction', got 0 0 0"},
        {"light sun directional direction 0 -1 0 intensity 5\nframe a\n",
         "variants.script:1:40: expected a directional light property (direction, illuminance, color), "
         "got 'intensity'"},
        {"light k point position 0 0 0\nframe a\n",
         "variants.script:1:9: expected 'intensity' for point light 'k'"},
        {"light s spot position 0 0 0 direction 0 0 1 intensity 3\nframe a\n",
         "variants.script:1:9: expected 'outer' for spot light 's'"},
        {"light k point position 0 0 0 intensity 1 intensity 2\nframe a\n",
         "variants.script:1:42: expected 'intensity' only once, got it again"},
        {"light k point position 0 0 0 intensity -2\nframe a\n",
         "variants.script:1:40: expected 'intensity' >= 0, got '-2'"},
        /* a strength the images' floats cannot hold (1e38 cd made infinite pixels) */
        {"light k point position 0 0 0 intensity 2e15\nframe a\n",
         "variants.script:1:40: expected 'intensity' at most 1e15 (beyond the range of the images' floats), "
         "got '2e15'"},
        {"light sun directional direction 0 -1 0 illuminance 1e20\nframe a\n",
         "variants.script:1:52: expected 'illuminance' at most 1e15 (beyond the range of the images' floats), "
         "got '1e20'"},
        {"light k point position 0 0 0 intensity 1 color 1 1e16 1\nframe a\n",
         "variants.script:1:50: expected 'color' at most 1e15 (beyond the range of the images' floats), "
         "got '1e16'"},
        {"material Floor emission 3e15 0 0\nframe a\n",
         "variants.script:1:25: expected 'emission' at most 1e15 (beyond the range of the images' floats), "
         "got '3e15'"},
        {"light p area center 0 0 0 u 1 0 0 v 2 0 0 luminance 1\nframe a\n",
         "variants.script:1:37: expected 'v' not parallel to 'u', got 2 0 0"},
        {"frame a\nresolution 0 480\nframe b\n",
         "variants.script:2:12: expected a width (an integer in 1..16384) after 'resolution', got '0'"},
        {"resolution 640 16385\nframe a\n",
         "variants.script:1:16: expected a height (an integer in 1..16384) after 'resolution', got '16385'"},
        {"resolution 640.5 480\nframe a\n",
         "variants.script:1:12: expected a width (an integer in 1..16384) after 'resolution', got '640.5'"},
        {"resolution 640\nframe a\n",
         "variants.script:1:15: expected a height (an integer in 1..16384) after 'resolution', got end of line"},
        {"resolution 640 480 1\nframe a\n", "variants.script:1:20: expected end of line, got '1'"},
        {"frame a\nframe b\n\nframe a\n",
         "variants.script:4:7: expected a unique frame name, got 'a' (already used on line 1)"},
        {"frame a b\n", "variants.script:1:9: expected end of line, got 'b'"},
        {"frame 12\n",
         "variants.script:1:7: expected a frame name that is not a number (it would read as a frame "
         "index), got '12'"},
        {"frame a/b\n",
         "variants.script:1:7: expected a frame name of letters, digits, '_', '-' and '.' starting with a "
         "letter, digit or '_', got 'a/b'"},
        {"frame\n", "variants.script:1:6: expected a frame name after 'frame', got end of line"},
        {"", "variants.script:1:1: expected at least one 'frame' command, got end of file"},
        {"resolution 10 10\n", "variants.script:2:1: expected at least one 'frame' command, got end of file"},
        {"# nothing\nresolution 10 10", "variants.script:2:17: expected at least one 'frame' command, got end of file"},
        {"frame a\nlight k point position 0 0 0 intensity 1\n# the end\n",
         "variants.script:2:1: expected a 'frame' command after this one: commands after the last frame "
         "have no effect"},
        {"material Floor\nframe a\n",
         "variants.script:1:15: expected a material property (basecolor, roughness, metallic, emission) "
         "after 'Floor', got end of line"},
        {"material Floor basecolor 1.5 0 0\nframe a\n",
         "variants.script:1:26: expected 'basecolor' in 0..1, got '1.5'"},
        {"material Floor shininess 3\nframe a\n",
         "variants.script:1:16: expected a material property (basecolor, roughness, metallic, emission), "
         "got 'shininess'"},
        {"material \"Left Wall roughness 1\nframe a\n",
         "variants.script:1:10: expected a closing '\"' before the end of the line"},
        {"material \"Left\"Wall roughness 1\nframe a\n",
         "variants.script:1:16: expected a space after the closing '\"', got 'W'"},
        {"material \"\" roughness 1\nframe a\n",
         "variants.script:1:10: expected a material name after 'material', got '\"\"'"},
        {"light aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa off\nframe a\n",
         "variants.script:1:7: expected a light name of at most 63 bytes, got "
         "'aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa...'"},
        {"camera\nframe a\n",
         "variants.script:1:7: expected 'gltf' or camera properties (position, target, direction, up, "
         "fov, near, far), got end of line"},
        {"camera gltf -1\nframe a\n",
         "variants.script:1:13: expected a camera index (an integer in 0..2147483647) after 'gltf', got '-1'"},
        {"camera position 0 0 0 fov 30\nframe a\n",
         "variants.script:1:1: expected 'target' or 'direction' for the camera"},
        {"camera position 0 0 0 target 0 0 0\nframe a\n",
         "variants.script:1:30: expected a 'target' different from 'position'"},
        {"camera position 0 0 0 target 0 1 0\nframe a\n",
         "variants.script:1:1: expected an 'up' vector not parallel to the view direction"},
        {"camera position 0 0 0 target 0 0 1 fov 180\nframe a\n",
         "variants.script:1:40: expected 'fov' between 0 and 180 degrees, got '180'"},
        {"camera position 0 0 0 target 0 0 1 direction 0 0 1\nframe a\n",
         "variants.script:1:36: expected either 'target' or 'direction', not both"},
        {"light on off\n\"frame\" a\n",
         "variants.script:2:1: expected a command (resolution, camera, light, material, frame), got "
         "'\"frame\"'"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++)
        expect_parse_error(cases[k].text, cases[k].msg);
    /* a NUL byte inside the text (parse_string takes a length) */
    const char nul[] = "frame a\nmaterial Fl\0or roughness 1\nframe b\n";
    gi_script *s = NULL;
    gi_status st = {0};
    assert_int_equal(gi_script_parse_string(nul, sizeof nul - 1, "variants.script", &s, &st), GI_EXIT_DATA);
    assert_string_equal(st.msg, "variants.script:2:12: expected text, got a NUL byte");
    assert_null(s);
}

static void test_check_errors(void **state)
{
    (void)state;
    expect_check_error("frame a\nmaterial Ceiling roughness 1\nframe b\n",
                       "variants.script:2:10: expected a material of scene 'test.gltf', got 'Ceiling'");
    expect_check_error("frame a\ncamera gltf 2\nframe b\n",
                       "variants.script:2:13: expected a camera index in 0..1 (scene 'test.gltf'), got '2'");
    expect_check_error("light ghost off\nframe a\n",
                       "variants.script:1:7: expected a light of scene 'test.gltf' or one defined earlier "
                       "in the script, got 'ghost'");
    /* defined only later: still an error where it is switched */
    expect_check_error("light x on\nframe a\nlight x point position 0 0 0 intensity 1\nframe b\n",
                       "variants.script:1:7: expected a light of scene 'test.gltf' or one defined earlier "
                       "in the script, got 'x'");
    /* the same problems reported by gi_script_frame for the frames they affect */
    gi_script *s = parse_ok("frame a\ncamera gltf 2\nmaterial Ceiling roughness 1\nframe b\n");
    gi_status st = {0};
    gi_frame f = {0};
    frame_ok(s, 0, &f);
    assert_false(f.has_camera);
    gi_frame_release(&f);
    assert_int_equal(gi_script_frame(s, scene(), 1, &f, &st), GI_EXIT_DATA);
    assert_string_equal(st.msg, "variants.script:2:13: expected a camera index in 0..1 (scene 'test.gltf'), got '2'");
    assert_null(f.lights);
    assert_int_equal(gi_script_frame(s, scene(), 2, &f, &st), GI_EXIT_USAGE);
    gi_script_free(s);
    s = parse_ok("material Ceiling roughness 1\nframe b\n");
    assert_int_equal(gi_script_frame(s, scene(), 0, &f, &st), GI_EXIT_DATA);
    assert_string_equal(st.msg, "variants.script:1:10: expected a material of scene 'test.gltf', got 'Ceiling'");
    gi_script_free(s);
    /* a scene without cameras */
    gi_scene sc = *scene();
    sc.num_cameras = 0;
    s = parse_ok("camera gltf 0\nframe a\n");
    assert_int_equal(gi_script_check(s, &sc, &st), GI_EXIT_DATA);
    assert_string_equal(st.msg, "variants.script:1:13: expected a camera index, got '0': scene 'test.gltf' has no cameras");
    gi_script_free(s);
    /* a good script passes */
    s = parse_ok("light x point position 0 0 0 intensity 1\nframe a\nlight x off\nlight key off\n"
                 "material \"Left Wall\" metallic 1\ncamera gltf 1\nframe b\n");
    assert_int_equal(gi_script_check(s, scene(), &st), 0);
    gi_script_free(s);
}

static void test_long_script(void **state)
{
    (void)state;
    const size_t nframes = 10000;
    size_t cap = nframes * 128, n = 0;
    char *text = malloc(cap);
    assert_non_null(text);
    n += (size_t)snprintf(text + n, cap - n, "camera gltf 0\nresolution 64 48\n");
    for (size_t i = 0; i < nframes; i++) {
        n += (size_t)snprintf(text + n, cap - n, "light moving point position %zu 2 0 intensity %zu\n",
                              i % 100, 10 + i);
        if (i % 1000 == 0)
            n += (size_t)snprintf(text + n, cap - n, "light key off\n");
        n += (size_t)snprintf(text + n, cap - n, "frame frame-%05zu\n", i);
    }
    double t0 = (double)clock() / CLOCKS_PER_SEC;
    gi_script *s = parse_ok(text);
    double t1 = (double)clock() / CLOCKS_PER_SEC;
    free(text);
    assert_int_equal(gi_script_num_frames(s), nframes);
    print_message("parse of %zu frames: %.3f s\n", nframes, t1 - t0);
    assert_true(t1 - t0 < 1.0);
    assert_int_equal(gi_script_find_frame(s, "frame-09999"), 9999);
    gi_status st = {0};
    assert_int_equal(gi_script_check(s, scene(), &st), 0);
    /* resolving every frame in turn stays linear in the number of frames */
    for (size_t i = 0; i < nframes; i++) {
        gi_frame f = {0};
        frame_ok(s, i, &f);
        const gi_light *m = &f.lights[NUM_LIGHTS];
        assert_float_equal(m->intensity, (float)(10 + i), 0);
        assert_float_equal(m->position[0], (float)(i % 100), 0);
        if (i > 0)
            assert_int_equal(f.changed, GI_CHANGED_LIGHTS);
        gi_frame_release(&f);
    }
    double t2 = (double)clock() / CLOCKS_PER_SEC;
    print_message("resolve of %zu frames: %.3f s\n", nframes, t2 - t1);
    assert_true(t2 - t1 < 5.0);
    gi_script_free(s);
}

static void test_frame_from_scene(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_frame f = {0};
    assert_int_equal(gi_frame_from_scene(scene(), &f, &st), 0);
    assert_int_equal(f.width, 640);
    assert_int_equal(f.height, 427); /* 640 / 1.5 */
    assert_true(f.has_camera);
    assert_string_equal(f.camera.name, "cam0");
    assert_int_equal(f.num_lights, NUM_LIGHTS);
    assert_int_equal(f.num_materials, NUM_MATS);
    assert_memory_equal(f.lights, g_lights, NUM_LIGHTS * sizeof *f.lights);
    assert_memory_equal(f.materials, g_mats, NUM_MATS * sizeof *f.materials);
    assert_int_equal(f.changed, GI_CHANGED_ALL);
    assert_int_equal(f.material_changed[NUM_MATS - 1], 1);
    gi_frame_release(&f);
    gi_scene sc = *scene();
    sc.num_cameras = 0;
    sc.num_lights = 0;
    assert_int_equal(gi_frame_from_scene(&sc, &f, &st), 0);
    assert_false(f.has_camera);
    assert_int_equal(f.height, 480);
    assert_int_equal(f.num_lights, 0);
    gi_frame_release(&f);
    gi_frame_release(&f); /* released twice / zeroed: fine */
    gi_frame_release(NULL);
    gi_script_free(NULL);
}

static void test_parse_file(void **state)
{
    (void)state;
    char path[] = "/tmp/test_script_XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    const char *text = "resolution 32 16\nframe only\n";
    assert_int_equal(write(fd, text, strlen(text)), (ssize_t)strlen(text));
    close(fd);
    gi_script *s = NULL;
    gi_status st = {0};
    assert_int_equal(gi_script_parse_file(path, &s, &st), 0);
    assert_int_equal(gi_script_num_frames(s), 1);
    gi_script_free(s);
    fd = open(path, O_WRONLY | O_TRUNC);
    assert_true(fd >= 0);
    text = "frame a\nresolution x 1\nframe b\n";
    assert_int_equal(write(fd, text, strlen(text)), (ssize_t)strlen(text));
    close(fd);
    assert_int_equal(gi_script_parse_file(path, &s, &st), GI_EXIT_DATA);
    char want[256];
    snprintf(want, sizeof want, "%s:2:12: expected a width (an integer in 1..16384) after 'resolution', got 'x'", path);
    assert_string_equal(st.msg, want);
    unlink(path);
    assert_int_equal(gi_script_parse_file(path, &s, &st), GI_EXIT_SYSTEM);
    assert_non_null(strstr(st.msg, path));
    assert_non_null(strstr(st.msg, "cannot open"));
    assert_null(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_issue_syntax),
        cmocka_unit_test(test_issue_lines_one_by_one),
        cmocka_unit_test(test_docs_example),
        cmocka_unit_test(test_camera_values),
        cmocka_unit_test(test_light_defaults_and_units),
        cmocka_unit_test(test_resolution),
        cmocka_unit_test(test_inheritance),
        cmocka_unit_test(test_replace_gltf_light),
        cmocka_unit_test(test_duplicate_scene_light_names),
        cmocka_unit_test(test_off_on),
        cmocka_unit_test(test_changed_flags),
        cmocka_unit_test(test_random_access),
        cmocka_unit_test(test_lexical),
        cmocka_unit_test(test_find_frame),
        cmocka_unit_test(test_parse_errors),
        cmocka_unit_test(test_check_errors),
        cmocka_unit_test(test_long_script),
        cmocka_unit_test(test_frame_from_scene),
        cmocka_unit_test(test_parse_file),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
