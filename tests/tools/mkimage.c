/* mkimage.c - test helper: write small images with known pixel values, or print
 * an image's size and pixels (for the CLI tests of gi-compare).
 *
 *   mkimage OUT W H C const V0 [V1 V2 V3]   every pixel = (V0, V1, ...); missing Vi = V0
 *   mkimage OUT W H C ramp BASE STEP        value(x,y,c) = BASE*(c+1) + STEP*(y*W + x)
 *   mkimage OUT W H C nan|inf X Y CH        constant 1, one NaN/+Inf at pixel (X,Y) channel CH
 *   mkimage OUT W H C spot V X Y S          constant V, the pixel (X,Y) set to S in all channels
 *   mkimage -i FILE [X Y [N]]               print "W H C", or the values of N pixels (default 1)
 *                                           from (X,Y) along the row, one line each (x255 for PNG)
 * OUT ending in .png is written with gi_image_write_png (values clamped to [0,1]),
 * anything else as float EXR. Exit 0, 2 on usage errors, else the gi_image code. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gi_image.h"

static int usage(void)
{
    fprintf(stderr, "usage: mkimage OUT W H C const|ramp|nan|inf|spot ARGS...\n"
                    "       mkimage -i FILE [X Y]\n");
    return 2;
}

static int num(const char *s, double *v)
{
    char *end;
    *v = strtod(s, &end);
    return end != s && *end == '\0';
}

static int info(int argc, char **argv)
{
    gi_status st = {0};
    gi_image im = {0, 0, 0, NULL};
    if (argc != 3 && argc != 5 && argc != 6)
        return usage();
    int rc = gi_image_read(argv[2], &im, &st);
    if (rc) {
        fprintf(stderr, "mkimage: %s\n", st.msg);
        return rc;
    }
    if (argc == 3) {
        printf("%d %d %d\n", im.width, im.height, im.channels);
    } else {
        int x = atoi(argv[3]), y = atoi(argv[4]), n = argc == 6 ? atoi(argv[5]) : 1;
        if (x < 0 || y < 0 || n < 1 || x >= im.width || y >= im.height || n > im.width - x) {
            gi_image_release(&im);
            return usage();
        }
        size_t len = strlen(argv[2]);
        int png = len > 4 && !strcmp(argv[2] + len - 4, ".png");
        for (int i = 0; i < n; i++) {
            const float *p = im.pixels + ((size_t)y * (size_t)im.width + (size_t)(x + i)) *
                                             (size_t)im.channels;
            for (int c = 0; c < im.channels; c++)
                printf(c ? " %.9g" : "%.9g", png ? (double)lrintf(p[c] * 255.0f) : (double)p[c]);
            printf("\n");
        }
    }
    gi_image_release(&im);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc >= 2 && !strcmp(argv[1], "-i"))
        return info(argc, argv);
    if (argc < 6)
        return usage();
    const char *out = argv[1], *mode = argv[5];
    double w, h, c;
    if (!num(argv[2], &w) || !num(argv[3], &h) || !num(argv[4], &c) || c < 1 || c > 4)
        return usage();
    gi_status st = {0};
    gi_image im = {0, 0, 0, NULL};
    int rc = gi_image_init(&im, (int)w, (int)h, (int)c, &st);
    if (rc) {
        fprintf(stderr, "mkimage: %s\n", st.msg);
        return rc;
    }
    int nc = im.channels, W = im.width;
    size_t npix = (size_t)im.width * (size_t)im.height;
    double a[4];
    int na = argc - 6;
    int bad = na > 4;
    for (int i = 0; i < na && !bad; i++)
        bad = !num(argv[6 + i], &a[i]);
    if (bad) {
        gi_image_release(&im);
        return usage();
    }
    if (!strcmp(mode, "const") && na >= 1) {
        for (size_t i = 0; i < npix; i++)
            for (int k = 0; k < nc; k++)
                im.pixels[i * (size_t)nc + (size_t)k] = (float)(k < na ? a[k] : a[0]);
    } else if (!strcmp(mode, "ramp") && na == 2) {
        for (size_t i = 0; i < npix; i++)
            for (int k = 0; k < nc; k++)
                im.pixels[i * (size_t)nc + (size_t)k] = (float)(a[0] * (k + 1) + a[1] * (double)i);
    } else if ((!strcmp(mode, "nan") || !strcmp(mode, "inf")) && na == 3) {
        for (size_t i = 0; i < npix * (size_t)nc; i++)
            im.pixels[i] = 1.0f;
        if (a[0] < 0 || a[1] < 0 || a[2] < 0 || a[0] >= W || a[1] >= im.height || a[2] >= nc) {
            gi_image_release(&im);
            return usage();
        }
        size_t at = ((size_t)a[1] * (size_t)W + (size_t)a[0]) * (size_t)nc + (size_t)a[2];
        im.pixels[at] = mode[0] == 'n' ? NAN : INFINITY;
    } else if (!strcmp(mode, "spot") && na == 4) {
        if (a[1] < 0 || a[2] < 0 || a[1] >= W || a[2] >= im.height) {
            gi_image_release(&im);
            return usage();
        }
        for (size_t i = 0; i < npix * (size_t)nc; i++)
            im.pixels[i] = (float)a[0];
        size_t at = ((size_t)a[2] * (size_t)W + (size_t)a[1]) * (size_t)nc;
        for (int k = 0; k < nc; k++)
            im.pixels[at + (size_t)k] = (float)a[3];
    } else {
        gi_image_release(&im);
        return usage();
    }
    size_t len = strlen(out);
    if (len > 4 && !strcmp(out + len - 4, ".png"))
        rc = gi_image_write_png(out, &im, &st);
    else
        rc = gi_image_write_exr(out, &im, NULL, 0, &st);
    if (rc)
        fprintf(stderr, "mkimage: %s\n", st.msg);
    gi_image_release(&im);
    return rc;
}
