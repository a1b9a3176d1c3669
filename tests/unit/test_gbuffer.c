/* test_gbuffer.c - the OSMesa G-buffer sees what the path tracer's camera
 * rays see: same triangle at the same sub-pixel positions, barycentrics that
 * rebuild the same point. */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gi_gbuffer.h"
#include "gi_gltf_write.h"
#include "gi_log.h"
#include "gi_pt.h"
#include "gi_rt.h"

static void test_gbuffer_matches_camera_rays(void **state)
{
    (void)state;
    char dir[] = "/tmp/gi_test_gb.XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[256];
    snprintf(path, sizeof path, "%s/s.gltf", dir);
    gi_gltf_builder *b = gi_gltf_builder_new();
    float grey[3] = {0.5f, 0.5f, 0.5f};
    int m = gi_gltf_add_material(b, "g", grey, 1.0f, 0.0f, NULL, 0);
    float lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
    gi_gltf_add_box(b, lo, hi, m, 1);
    float blo[3] = {-0.3f, -1, -0.2f}, bhi[3] = {0.2f, 0.1f, 0.4f};
    gi_gltf_add_box(b, blo, bhi, m, 0);
    gi_status st = {0};
    assert_int_equal(gi_gltf_builder_write(b, path, &st), 0);
    gi_gltf_builder_free(b);
    gi_scene *s = NULL;
    assert_int_equal(gi_scene_load(path, &s, &st), 0);
    gi_rt *rt = NULL;
    assert_int_equal(gi_rt_new(s, &rt, &st), 0);
    gi_gbuffer *gb = NULL;
    if (gi_gbuffer_new(s, &gb, &st))
        fail_msg("%s", st.msg);
    gi_camera cam;
    memset(&cam, 0, sizeof cam);
    cam.position[0] = 0.1f;
    cam.position[1] = 0.2f;
    cam.position[2] = -0.9f;
    gi_vec3 fwd = gi_norm(gi_v3(0.1f, -0.1f, 1.0f));
    gi_v3store(cam.forward, fwd);
    gi_vec3 up = gi_norm(gi_cross(gi_cross(fwd, gi_v3(0, 1, 0)), fwd));
    gi_v3store(cam.up, up);
    cam.yfov = 1.1f;
    const int W = 48, H = 32;
    gi_gpixel *px = malloc((size_t)W * H * sizeof *px);
    const float jit[3][2] = {{0.5f, 0.5f}, {0.125f, 0.875f}, {0.8f, 0.2f}};
    for (int j = 0; j < 3; j++) {
        assert_int_equal(gi_gbuffer_render(gb, &cam, W, H, jit[j][0], jit[j][1], px, &st), 0);
        int mismatch = 0, far = 0;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                gi_vec3 o, d;
                gi_camera_ray(&cam, W, H, (float)x + jit[j][0], (float)y + jit[j][1], &o, &d);
                gi_hit h;
                int hit = gi_rt_intersect(rt, o, d, 0.0f, INFINITY, &h);
                const gi_gpixel *g = &px[y * W + x];
                if (!hit || g->tri != h.tri + 1) {
                    mismatch++;
                    continue;
                }
                gi_hit gh = {0, g->tri - 1, g->u, g->v};
                gi_surface a, c;
                gi_rt_surface(rt, &h, &a);
                gi_rt_surface(rt, &gh, &c);
                if (gi_len(gi_sub(a.p, c.p)) > 1e-3f)
                    far++;
            }
        /* packets of a row's rays find exactly what single rays find */
        int differ = 0;
        for (int y = 0; y < H; y++) {
            gi_vec3 o[W], d[W];
            gi_hit hn[W];
            uint8_t found[W];
            for (int x = 0; x < W; x++)
                gi_camera_ray(&cam, W, H, (float)x + jit[j][0], (float)y + jit[j][1], &o[x], &d[x]);
            gi_rt_intersect_n(rt, W, o, d, 0.0f, hn, found);
            for (int x = 0; x < W; x++) {
                gi_hit h1;
                int hit = gi_rt_intersect(rt, o[x], d[x], 0.0f, INFINITY, &h1);
                differ += hit != found[x] || (hit && (h1.tri != hn[x].tri || h1.t != hn[x].t || h1.u != hn[x].u ||
                                                      h1.v != hn[x].v));
            }
        }
        assert_int_equal(differ, 0);
        print_message("jitter (%.3f, %.3f): %d of %d pixels see another triangle, %d another point\n", jit[j][0],
                      jit[j][1], mismatch, W * H, far);
        /* a few pixels may straddle an edge or a triangle diagonal */
        assert_true(mismatch <= W * H / 100);
        assert_true(far <= W * H / 100);
    }
    free(px);
    gi_gbuffer_free(gb);
    gi_rt_free(rt);
    gi_scene_free(s);
    unlink(path);
    rmdir(dir);
}

int main(void)
{
    gi_log_set_verbosity(-1);
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_gbuffer_matches_camera_rays)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
