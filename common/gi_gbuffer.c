/* gi_gbuffer.c - triangle-id + barycentric G-buffer on OSMesa (GL 4.5 core). */
#define _POSIX_C_SOURCE 200809L
#define GL_GLEXT_PROTOTYPES 1
#include "gi_gbuffer.h"

#include <GL/osmesa.h>
#include <GL/gl.h>
#include <GL/glext.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gi_math.h"

struct gi_gbuffer {
    OSMesaContext ctx;
    unsigned char dummy[4 * 4];
    GLuint prog, vao, vbo, fbo, color, depth;
    PFNGLCLIPCONTROLPROC clip_control; /* (GL 4.5; libOSMesa does not export it) */
    int fw, fh;            /* framebuffer size */
    size_t nverts;
    float near_, far_;
    float *readback;       /* 4 floats per pixel */
    char renderer[160];
};

static const char *vs_src =
    "#version 450 core\n"
    "layout(location = 0) in vec3 pos;\n"
    "layout(location = 1) in vec2 bary;\n"
    "uniform mat4 mvp;\n"
    "out vec2 vb;\n"
    "void main() { vb = bary; gl_Position = mvp * vec4(pos, 1.0); }\n";

/* Triangle index travels as the bits of a float: exact for any count. */
static const char *fs_src =
    "#version 450 core\n"
    "in vec2 vb;\n"
    "out vec4 o;\n"
    "void main() { o = vec4(uintBitsToFloat(uint(gl_PrimitiveID) + 1u), vb.x, vb.y, 0.0); }\n";

static int compile(GLenum type, const char *src, GLuint *out, gi_status *st)
{
    GLuint sh = glCreateShader(type);
    glShaderSource(sh, 1, &src, NULL);
    glCompileShader(sh);
    GLint ok = 0;
    glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[1024];
        glGetShaderInfoLog(sh, sizeof log, NULL, log);
        glDeleteShader(sh);
        return gi_status_set(st, GI_EXIT_SYSTEM, "OSMesa: shader compilation failed: %s", log);
    }
    *out = sh;
    return 0;
}

int gi_gbuffer_new(const gi_scene *s, gi_gbuffer **out, gi_status *st)
{
    *out = NULL;
    gi_gbuffer *g = calloc(1, sizeof *g);
    if (!g)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    const int attrs[] = {OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS, 0, OSMESA_PROFILE,
                         OSMESA_CORE_PROFILE, OSMESA_CONTEXT_MAJOR_VERSION, 4,
                         OSMESA_CONTEXT_MINOR_VERSION, 5, 0};
    g->ctx = OSMesaCreateContextAttribs(attrs, NULL);
    if (!g->ctx) {
        free(g);
        return gi_status_set(st, GI_EXIT_SYSTEM, "OSMesa: cannot create a GL 4.5 core context");
    }
    if (!OSMesaMakeCurrent(g->ctx, g->dummy, GL_UNSIGNED_BYTE, 2, 2)) {
        OSMesaDestroyContext(g->ctx);
        free(g);
        return gi_status_set(st, GI_EXIT_SYSTEM, "OSMesa: cannot make the context current");
    }
    g->clip_control = (PFNGLCLIPCONTROLPROC)OSMesaGetProcAddress("glClipControl");
    if (!g->clip_control) {
        OSMesaDestroyContext(g->ctx);
        free(g);
        return gi_status_set(st, GI_EXIT_SYSTEM, "OSMesa: no glClipControl (GL 4.5)");
    }
    snprintf(g->renderer, sizeof g->renderer, "%s (%s)", (const char *)glGetString(GL_VERSION),
             (const char *)glGetString(GL_RENDERER));
    GLuint vs, fs;
    int rc = compile(GL_VERTEX_SHADER, vs_src, &vs, st);
    if (!rc)
        rc = compile(GL_FRAGMENT_SHADER, fs_src, &fs, st);
    if (rc) {
        gi_gbuffer_free(g);
        return rc;
    }
    g->prog = glCreateProgram();
    glAttachShader(g->prog, vs);
    glAttachShader(g->prog, fs);
    glLinkProgram(g->prog);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(g->prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        gi_gbuffer_free(g);
        return gi_status_set(st, GI_EXIT_SYSTEM, "OSMesa: shader link failed");
    }
    /* non-indexed triangles: 3 vertices each with (position, barycentric) */
    g->nverts = 3 * s->num_triangles;
    float *vb = malloc((g->nverts + 1) * 5 * sizeof *vb);
    if (!vb) {
        gi_gbuffer_free(g);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %zu vertices", g->nverts);
    }
    static const float bc[3][2] = {{0, 0}, {1, 0}, {0, 1}};
    for (size_t t = 0; t < s->num_triangles; t++)
        for (int k = 0; k < 3; k++) {
            const float *p = s->positions + 3 * (size_t)s->indices[3 * t + k];
            float *d = vb + 5 * (3 * t + (size_t)k);
            d[0] = p[0];
            d[1] = p[1];
            d[2] = p[2];
            d[3] = bc[k][0];
            d[4] = bc[k][1];
        }
    glGenVertexArrays(1, &g->vao);
    glBindVertexArray(g->vao);
    glGenBuffers(1, &g->vbo);
    glBindBuffer(GL_ARRAY_BUFFER, g->vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(g->nverts * 5 * sizeof *vb), vb, GL_STATIC_DRAW);
    free(vb);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 5 * sizeof(float), (void *)0);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, 5 * sizeof(float), (void *)(3 * sizeof(float)));
    glEnableVertexAttribArray(1);
    /* depth range from the scene's extent */
    float ext = 0.0f;
    for (int a = 0; a < 3; a++)
        ext = fmaxf(ext, s->bbox_max[a] - s->bbox_min[a]);
    g->far_ = fmaxf(ext, 1e-3f);
    if (glGetError() != GL_NO_ERROR) {
        gi_gbuffer_free(g);
        return gi_status_set(st, GI_EXIT_SYSTEM, "OSMesa: GL error while uploading geometry");
    }
    *out = g;
    return 0;
}

static int ensure_fbo(gi_gbuffer *g, int w, int h, gi_status *st)
{
    if (g->fbo && g->fw == w && g->fh == h)
        return 0;
    if (g->fbo) {
        glDeleteFramebuffers(1, &g->fbo);
        glDeleteRenderbuffers(1, &g->color);
        glDeleteRenderbuffers(1, &g->depth);
    }
    glGenFramebuffers(1, &g->fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, g->fbo);
    glGenRenderbuffers(1, &g->color);
    glBindRenderbuffer(GL_RENDERBUFFER, g->color);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA32F, w, h);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, g->color);
    glGenRenderbuffers(1, &g->depth);
    glBindRenderbuffer(GL_RENDERBUFFER, g->depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, w, h);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, g->depth);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        return gi_status_set(st, GI_EXIT_SYSTEM, "OSMesa: %dx%d float framebuffer incomplete", w, h);
    free(g->readback);
    g->readback = malloc((size_t)w * (size_t)h * 4 * sizeof *g->readback);
    if (!g->readback)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for a %dx%d G-buffer", w, h);
    g->fw = w;
    g->fh = h;
    return 0;
}

/* Column-major perspective * view, with the projection centre shifted so the
 * sample sits at (jx, jy) inside each pixel. Reversed depth (with clip control
 * 0..1 and a float buffer): depth = nearz / distance to an infinite far plane
 * (farz 0), else 1 at nearz falling to 0 at farz. A float's relative precision
 * then holds at every distance; the usual mapping crowds far depths below the
 * float's resolution near 1: at 30 m with the near plane at 1 cm it told depths
 * ~5 mm apart, at 8 km ~400 m (the Cornell box scaled by 10,000: the blocks'
 * faces lost to the floor along their feet, 0.06 nrmse of direct light). */
static void view_proj(const gi_camera *cam, int w, int h, float jx, float jy, float nearz, float farz,
                      float m[16])
{
    gi_vec3 f = gi_norm(gi_v3p(cam->forward)), up = gi_norm(gi_v3p(cam->up));
    gi_vec3 r = gi_norm(gi_cross(f, up));
    up = gi_cross(r, f);
    gi_vec3 e = gi_v3p(cam->position);
    float th = tanf(0.5f * cam->yfov), aspect = (float)w / (float)h;
    /* NDC of the sample offset: pixel centre is at 0.5; shift the image so
     * sample (jx, jy) lands on the pixel centre of the rasteriser */
    float sx = (0.5f - jx) * 2.0f / (float)w, sy = (jy - 0.5f) * 2.0f / (float)h;
    float P[16] = {0};
    P[0] = 1.0f / (th * aspect);
    P[5] = 1.0f / th;
    P[8] = sx;
    P[9] = sy;
    /* clip z = P[10] z_eye + P[14] over w = -z_eye (the distance d):
     * infinite, n / d; finite, n (f - d) / ((f - n) d) */
    P[10] = farz > 0.0f ? nearz / (farz - nearz) : 0.0f;
    P[11] = -1.0f;
    P[14] = farz > 0.0f ? farz * nearz / (farz - nearz) : nearz;
    /* P[8], P[9] multiply view-space z (= -depth): x_ndc += sx, y_ndc += sy after the divide */
    P[8] = -sx;
    P[9] = -sy;
    float V[16] = {r.x, up.x, -f.x, 0, r.y, up.y, -f.y, 0, r.z, up.z, -f.z, 0,
                   -gi_dot(r, e), -gi_dot(up, e), gi_dot(f, e), 1};
    for (int c = 0; c < 4; c++)
        for (int rr = 0; rr < 4; rr++) {
            float acc = 0.0f;
            for (int k = 0; k < 4; k++)
                acc += P[k * 4 + rr] * V[c * 4 + k];
            m[c * 4 + rr] = acc;
        }
}

int gi_gbuffer_render(gi_gbuffer *g, const gi_camera *cam, int w, int h, float jx, float jy,
                      gi_gpixel *px, gi_status *st)
{
    if (!OSMesaMakeCurrent(g->ctx, g->dummy, GL_UNSIGNED_BYTE, 2, 2))
        return gi_status_set(st, GI_EXIT_SYSTEM, "OSMesa: cannot make the context current");
    int rc = ensure_fbo(g, w, h, st);
    if (rc)
        return rc;
    /* near plane: a small fraction of the scene, never behind the camera;
     * no far plane unless the camera has one */
    float farz = 0.0f;
    float nearz = fmaxf(g->far_ * 1e-4f, 1e-4f);
    if (cam->znear > 0.0f)
        nearz = cam->znear;
    if (cam->zfar > nearz)
        farz = cam->zfar;
    float m[16];
    view_proj(cam, w, h, jx, jy, nearz, farz, m);
    glBindFramebuffer(GL_FRAMEBUFFER, g->fbo);
    glViewport(0, 0, w, h);
    glDisable(GL_CULL_FACE);
    glEnable(GL_DEPTH_TEST);
    g->clip_control(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
    glDepthFunc(GL_GREATER); /* reversed: nearer is greater */
    glClearColor(0.0f, 0.0f, 0.0f, 0.0f);
    glClearDepth(0.0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glUseProgram(g->prog);
    glUniformMatrix4fv(glGetUniformLocation(g->prog, "mvp"), 1, GL_FALSE, m);
    glBindVertexArray(g->vao);
    glDrawArrays(GL_TRIANGLES, 0, (GLsizei)g->nverts);
    glReadPixels(0, 0, w, h, GL_RGBA, GL_FLOAT, g->readback);
    if (glGetError() != GL_NO_ERROR)
        return gi_status_set(st, GI_EXIT_SYSTEM, "OSMesa: GL error while rendering the G-buffer");
    for (int y = 0; y < h; y++) {
        const float *row = g->readback + 4 * (size_t)(h - 1 - y) * (size_t)w;
        for (int x = 0; x < w; x++) {
            gi_gpixel *d = &px[(size_t)y * (size_t)w + (size_t)x];
            memcpy(&d->tri, &row[4 * x], 4);
            d->u = row[4 * x + 1];
            d->v = row[4 * x + 2];
        }
    }
    return 0;
}

void gi_gbuffer_free(gi_gbuffer *g)
{
    if (!g)
        return;
    if (g->ctx) {
        OSMesaMakeCurrent(g->ctx, g->dummy, GL_UNSIGNED_BYTE, 2, 2);
        if (g->fbo) {
            glDeleteFramebuffers(1, &g->fbo);
            glDeleteRenderbuffers(1, &g->color);
            glDeleteRenderbuffers(1, &g->depth);
        }
        if (g->vbo)
            glDeleteBuffers(1, &g->vbo);
        if (g->vao)
            glDeleteVertexArrays(1, &g->vao);
        if (g->prog)
            glDeleteProgram(g->prog);
        OSMesaDestroyContext(g->ctx);
    }
    free(g->readback);
    free(g);
}

const char *gi_gbuffer_renderer(const gi_gbuffer *g) { return g->renderer; }
