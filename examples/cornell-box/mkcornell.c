/* mkcornell.c - write the measured Cornell box (Cornell Program of Computer
 * Graphics, published data) as a self-contained glTF 2.0 file.
 *
 * Usage: mkcornell [-q|-v] OUT.gltf
 *
 * Geometry: the published quads, millimetres converted to metres, published
 * coordinates kept (right-handed, +y up, camera at (0.278, 0.273, -0.800)
 * looking along +z, so +x is image-left and the red wall at x ~ 0.55 m is on
 * the left). Each quad is oriented so its front faces the inside of the room
 * (walls) or the outside of a block; the light quad is not geometry. Seven named
 * Lambertian materials (roughness 1, metallic 0, single-sided: walls face into the box, blocks face out) so variant
 * scripts can change each: Floor, Ceiling, BackWall, LeftWall (red),
 * RightWall (green), ShortBlock, TallBlock.
 *
 * Albedos: the published 4 nm reflectance spectra integrated against the
 * CIE 1931 2-degree colour matching functions (the multi-lobe Gaussian fit of
 * Wyman, Sloan and Shirley 2013) under equal-energy illuminant E, normalised so
 * a reflectance of 1 gives Y = 1, then XYZ -> linear sRGB. Printed on stderr.
 *
 * Lights and camera: a 2 cd white point light "ceiling" just under the
 * published light, and the published camera "published" (yfov 39.31 deg,
 * aspect 1). Exit status: 0, 2 usage, 4 I/O. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gi_exit.h"
#include "gi_gltf_write.h"
#include "gi_log.h"
#include "gi_status.h"

/* ---- published reflectance spectra, 400..700 nm in 4 nm steps ----------- */

#define SPEC_N 76
#define SPEC_L0 400.0
#define SPEC_DL 4.0

static const double spec_white[SPEC_N] = {
    0.343, 0.445, 0.551, 0.624, 0.665, 0.687, 0.708, 0.723, 0.715, 0.710, 0.745, 0.758, 0.739,
    0.767, 0.777, 0.765, 0.751, 0.745, 0.748, 0.729, 0.745, 0.757, 0.753, 0.750, 0.746, 0.747,
    0.735, 0.732, 0.739, 0.734, 0.725, 0.721, 0.733, 0.725, 0.732, 0.743, 0.744, 0.748, 0.728,
    0.716, 0.733, 0.726, 0.713, 0.740, 0.754, 0.764, 0.752, 0.736, 0.734, 0.741, 0.740, 0.732,
    0.745, 0.755, 0.751, 0.744, 0.731, 0.733, 0.744, 0.731, 0.712, 0.708, 0.729, 0.730, 0.727,
    0.707, 0.703, 0.729, 0.750, 0.760, 0.751, 0.739, 0.724, 0.730, 0.740, 0.737};
static const double spec_green[SPEC_N] = {
    0.092, 0.096, 0.098, 0.097, 0.098, 0.095, 0.095, 0.097, 0.095, 0.094, 0.097, 0.098, 0.096,
    0.101, 0.103, 0.104, 0.107, 0.109, 0.112, 0.115, 0.125, 0.140, 0.160, 0.187, 0.229, 0.285,
    0.343, 0.390, 0.435, 0.464, 0.472, 0.476, 0.481, 0.462, 0.447, 0.441, 0.426, 0.406, 0.373,
    0.347, 0.337, 0.314, 0.285, 0.277, 0.266, 0.250, 0.230, 0.207, 0.186, 0.171, 0.160, 0.148,
    0.141, 0.136, 0.130, 0.126, 0.123, 0.121, 0.122, 0.119, 0.114, 0.115, 0.117, 0.117, 0.118,
    0.120, 0.122, 0.128, 0.132, 0.139, 0.144, 0.146, 0.150, 0.152, 0.157, 0.159};
static const double spec_red[SPEC_N] = {
    0.040, 0.046, 0.048, 0.053, 0.049, 0.050, 0.053, 0.055, 0.057, 0.056, 0.059, 0.057, 0.061,
    0.061, 0.060, 0.062, 0.062, 0.062, 0.061, 0.062, 0.060, 0.059, 0.057, 0.058, 0.058, 0.058,
    0.056, 0.055, 0.056, 0.059, 0.057, 0.055, 0.059, 0.059, 0.058, 0.059, 0.061, 0.061, 0.063,
    0.063, 0.067, 0.068, 0.072, 0.080, 0.090, 0.099, 0.124, 0.154, 0.192, 0.255, 0.287, 0.349,
    0.402, 0.443, 0.487, 0.513, 0.558, 0.584, 0.620, 0.606, 0.609, 0.651, 0.612, 0.610, 0.650,
    0.638, 0.627, 0.620, 0.630, 0.628, 0.642, 0.639, 0.657, 0.639, 0.635, 0.642};

/* Reflectance at wavelength l (nm): linear interpolation of the table, held
 * constant outside 400..700 nm (the measurement range). */
static double spec_at(const double *s, double l)
{
    double t = (l - SPEC_L0) / SPEC_DL;
    if (t <= 0.0)
        return s[0];
    if (t >= SPEC_N - 1)
        return s[SPEC_N - 1];
    int i = (int)t;
    double f = t - i;
    return s[i] * (1.0 - f) + s[i + 1] * f;
}

/* ---- CIE 1931 2-degree CMFs: Wyman, Sloan, Shirley (2013) multi-lobe fit - */

/* Piecewise Gaussian: width s1 left of the mean, s2 right of it. */
static double lobe(double l, double mu, double s1, double s2)
{
    double t = (l - mu) / (l < mu ? s1 : s2);
    return exp(-0.5 * t * t);
}

static void cmf(double l, double xyz[3])
{
    xyz[0] = 1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7) -
             0.065 * lobe(l, 501.1, 20.4, 26.2);
    xyz[1] = 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
    xyz[2] = 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8);
}

/* Linear sRGB albedo of a reflectance spectrum under illuminant E.
 * XYZ = integral(rho * cmf) / integral(ybar) over 360..830 nm in 1 nm steps,
 * so rho = 1 gives Y = 1 (and X, Z close to 1: E is the CIE's equal-energy
 * white). The matrix is the standard XYZ -> linear sRGB one, whose white is
 * D65; no chromatic adaptation is applied from E to D65, so a spectrally flat
 * grey comes out slightly pink (E maps to about (1.20, 0.95, 0.91)). That is
 * what the published spectra say under an equal-energy light, and it is how
 * the widely used RGB renditions of the box were made too. Results are
 * clamped to [0, 1]. */
static void albedo_rgb(const double *s, float rgb[3])
{
    double X = 0.0, Y = 0.0, Z = 0.0, norm = 0.0;
    for (int l = 360; l <= 830; l++) {
        double c[3];
        cmf((double)l, c);
        double r = spec_at(s, (double)l);
        X += r * c[0];
        Y += r * c[1];
        Z += r * c[2];
        norm += c[1];
    }
    X /= norm;
    Y /= norm;
    Z /= norm;
    double lin[3] = {3.2404542 * X - 1.5371385 * Y - 0.4985314 * Z,
                     -0.9692660 * X + 1.8760108 * Y + 0.0415560 * Z,
                     0.0556434 * X - 0.2040259 * Y + 1.0572252 * Z};
    for (int k = 0; k < 3; k++)
        rgb[k] = (float)(lin[k] < 0.0 ? 0.0 : (lin[k] > 1.0 ? 1.0 : lin[k]));
}

/* Relative spectral radiance of the light as published (400..700 nm, 100 nm
 * steps, no absolute units). */
static const double spec_light[4] = {0.0, 8.0, 15.6, 18.4};

/* Linear sRGB colour of the published light spectrum, scaled so its luminance
 * (Y, = 0.2126 R + 0.7152 G + 0.0722 B) is 1: a script's `color` for an area
 * light whose `luminance` is then its luminance in nits. Same integration and
 * matrix as albedo_rgb; the spectrum is interpolated linearly between its
 * 100 nm samples and held constant outside 400..700 nm. */
static void light_rgb(float rgb[3])
{
    double X = 0.0, Y = 0.0, Z = 0.0;
    for (int l = 360; l <= 830; l++) {
        double t = (l - 400.0) / 100.0, e;
        if (t <= 0.0)
            e = spec_light[0];
        else if (t >= 3.0)
            e = spec_light[3];
        else {
            int i = (int)t;
            e = spec_light[i] * (1.0 - (t - i)) + spec_light[i + 1] * (t - i);
        }
        double c[3];
        cmf((double)l, c);
        X += e * c[0];
        Y += e * c[1];
        Z += e * c[2];
    }
    X /= Y;
    Z /= Y;
    Y = 1.0;
    double lin[3] = {3.2404542 * X - 1.5371385 * Y - 0.4985314 * Z,
                     -0.9692660 * X + 1.8760108 * Y + 0.0415560 * Z,
                     0.0556434 * X - 0.2040259 * Y + 1.0572252 * Z};
    for (int k = 0; k < 3; k++)
        rgb[k] = (float)(lin[k] < 0.0 ? 0.0 : lin[k]);
}

/* ---- geometry (published vertex lists, millimetres) -------------------- */

typedef struct quad_mm {
    double v[4][3];
} quad_mm;

static const quad_mm floor_q = {{{552.8, 0, 0}, {0, 0, 0}, {0, 0, 559.2}, {549.6, 0, 559.2}}};
static const quad_mm ceiling_q = {
    {{556.0, 548.8, 0}, {556.0, 548.8, 559.2}, {0, 548.8, 559.2}, {0, 548.8, 0}}};
static const quad_mm back_q = {
    {{549.6, 0, 559.2}, {0, 0, 559.2}, {0, 548.8, 559.2}, {556.0, 548.8, 559.2}}};
static const quad_mm right_q = {
    {{0, 0, 559.2}, {0, 0, 0}, {0, 548.8, 0}, {0, 548.8, 559.2}}};
static const quad_mm left_q = {
    {{552.8, 0, 0}, {549.6, 0, 559.2}, {556.0, 548.8, 559.2}, {556.0, 548.8, 0}}};

static const quad_mm short_q[5] = {
    {{{130, 165, 65}, {82, 165, 225}, {240, 165, 272}, {290, 165, 114}}},
    {{{290, 0, 114}, {290, 165, 114}, {240, 165, 272}, {240, 0, 272}}},
    {{{130, 0, 65}, {130, 165, 65}, {290, 165, 114}, {290, 0, 114}}},
    {{{82, 0, 225}, {82, 165, 225}, {130, 165, 65}, {130, 0, 65}}},
    {{{240, 0, 272}, {240, 165, 272}, {82, 165, 225}, {82, 0, 225}}},
};
static const quad_mm tall_q[5] = {
    {{{423, 330, 247}, {265, 330, 296}, {314, 330, 456}, {472, 330, 406}}},
    {{{423, 0, 247}, {423, 330, 247}, {472, 330, 406}, {472, 0, 406}}},
    {{{472, 0, 406}, {472, 330, 406}, {314, 330, 456}, {314, 0, 456}}},
    {{{314, 0, 456}, {314, 330, 456}, {265, 330, 296}, {265, 0, 296}}},
    {{{265, 0, 296}, {265, 330, 296}, {423, 330, 247}, {423, 0, 247}}},
};

/* Add quad q (mm) as metres, flipped if needed so that its front face (counter-
 * clockwise winding) points away from `centre` (outward = 1, blocks) or
 * towards it (outward = 0, walls of the room). Returns 1 if it was flipped. */
static int add_oriented(gi_gltf_builder *b, const quad_mm *q, const double centre[3],
                        int outward, int mat)
{
    /* Newell's normal: robust for the slightly non-planar published quads. */
    double n[3] = {0, 0, 0}, c[3] = {0, 0, 0};
    for (int i = 0; i < 4; i++) {
        const double *a = q->v[i], *d = q->v[(i + 1) % 4];
        n[0] += (a[1] - d[1]) * (a[2] + d[2]);
        n[1] += (a[2] - d[2]) * (a[0] + d[0]);
        n[2] += (a[0] - d[0]) * (a[1] + d[1]);
        for (int k = 0; k < 3; k++)
            c[k] += 0.25 * a[k];
    }
    double side = 0.0;
    for (int k = 0; k < 3; k++)
        side += n[k] * (c[k] - centre[k]);
    int flip = outward ? side < 0.0 : side > 0.0;
    float p[4][3];
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 3; k++)
            p[i][k] = (float)(q->v[flip ? (4 - i) % 4 : i][k] / 1000.0);
    gi_gltf_add_quad(b, p[0], p[1], p[2], p[3], mat);
    return flip;
}

/* Centre of a block: mean of its top quad's corners at half the height. */
static void block_centre(const quad_mm *top, double c[3])
{
    c[0] = c[1] = c[2] = 0.0;
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 3; k++)
            c[k] += 0.25 * top->v[i][k];
    c[1] *= 0.5;
}

static void usage(FILE *f)
{
    fprintf(f, "usage: mkcornell [-q|-v] OUT.gltf\n"
               "Write the measured Cornell box (metres, published coordinates) as glTF 2.0.\n"
               "  -q, --quiet   do not print the derived albedos\n"
               "  -v, --verbose also say how many published quads were flipped\n"
               "  -h, --help    this text\n");
}

int main(int argc, char **argv)
{
    gi_log_init("mkcornell");
    const char *out = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(argv[i], "-q") || !strcmp(argv[i], "--quiet")) {
            gi_log_set_verbosity(-1);
        } else if (!strcmp(argv[i], "-v") || !strcmp(argv[i], "--verbose")) {
            gi_log_set_verbosity(1);
        } else if (argv[i][0] == '-' && argv[i][1]) {
            gi_usage_error("unknown option '%s'", argv[i]);
        } else if (out) {
            gi_usage_error("more than one output file ('%s', '%s')", out, argv[i]);
        } else {
            out = argv[i];
        }
    }
    if (!out)
        gi_usage_error("missing output file");

    float white[3], red[3], green[3];
    albedo_rgb(spec_white, white);
    albedo_rgb(spec_red, red);
    albedo_rgb(spec_green, green);
    gi_info("albedo (linear sRGB, illuminant E, CIE 1931 fit of Wyman et al. 2013):");
    gi_info("  white %.4f %.4f %.4f", (double)white[0], (double)white[1], (double)white[2]);
    gi_info("  red   %.4f %.4f %.4f", (double)red[0], (double)red[1], (double)red[2]);
    gi_info("  green %.4f %.4f %.4f", (double)green[0], (double)green[1], (double)green[2]);
    float lrgb[3];
    light_rgb(lrgb);
    gi_info("light colour (published spectrum, luminance 1): %.4f %.4f %.4f", (double)lrgb[0],
            (double)lrgb[1], (double)lrgb[2]);

    gi_gltf_builder *b = gi_gltf_builder_new();
    if (!b)
        gi_die(GI_EXIT_SYSTEM, "out of memory");
    int m_floor = gi_gltf_add_material(b, "Floor", white, 1.0f, 0.0f, NULL, 0);
    int m_ceil = gi_gltf_add_material(b, "Ceiling", white, 1.0f, 0.0f, NULL, 0);
    int m_back = gi_gltf_add_material(b, "BackWall", white, 1.0f, 0.0f, NULL, 0);
    int m_left = gi_gltf_add_material(b, "LeftWall", red, 1.0f, 0.0f, NULL, 0);
    int m_right = gi_gltf_add_material(b, "RightWall", green, 1.0f, 0.0f, NULL, 0);
    int m_short = gi_gltf_add_material(b, "ShortBlock", white, 1.0f, 0.0f, NULL, 0);
    int m_tall = gi_gltf_add_material(b, "TallBlock", white, 1.0f, 0.0f, NULL, 0);

    /* Room centre (mm): middle of the interior extents. */
    const double room[3] = {278.0, 274.4, 279.6};
    int flips = 0;
    flips += add_oriented(b, &floor_q, room, 0, m_floor);
    flips += add_oriented(b, &ceiling_q, room, 0, m_ceil);
    flips += add_oriented(b, &back_q, room, 0, m_back);
    flips += add_oriented(b, &left_q, room, 0, m_left);
    flips += add_oriented(b, &right_q, room, 0, m_right);
    double cs[3], ct[3];
    block_centre(&short_q[0], cs);
    block_centre(&tall_q[0], ct);
    for (int i = 0; i < 5; i++) {
        flips += add_oriented(b, &short_q[i], cs, 1, m_short);
        flips += add_oriented(b, &tall_q[i], ct, 1, m_tall);
    }
    gi_verbose("%d of 15 published quads flipped to face the right way", flips);

    const float lpos[3] = {0.278f, 0.450f, 0.2795f}, lcol[3] = {1.0f, 1.0f, 1.0f};
    gi_gltf_add_point_light(b, "ceiling", lpos, lcol, 2.0f);
    const float cpos[3] = {0.278f, 0.273f, -0.800f}, ctgt[3] = {0.278f, 0.273f, 0.0f};
    const float cup[3] = {0.0f, 1.0f, 0.0f};
    /* 2 atan(12.5 / 35): 25 mm film at 35 mm focal length, = 39.31 degrees. */
    gi_gltf_add_camera(b, "published", cpos, ctgt, cup, (float)(2.0 * atan(12.5 / 35.0)), 1.0f);

    gi_status st = {0};
    if (gi_gltf_builder_write(b, out, &st)) {
        gi_gltf_builder_free(b);
        gi_die_status(&st);
    }
    gi_info("wrote %s: %zu triangles, 7 materials, 1 light, 1 camera", out,
            gi_gltf_builder_triangles(b));
    gi_gltf_builder_free(b);
    return 0;
}
