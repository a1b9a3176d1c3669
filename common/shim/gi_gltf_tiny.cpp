// gi_gltf_tiny.cpp - glTF 2.0 (.gltf/.glb) loader: tinygltf parses, this file
// validates every index and byte range, flattens the node hierarchy into
// world-space triangles and fills a gi_scene (gi_scene.h). The only C++ file
// that includes tiny_gltf.h; the implementation comes from Debian's
// libtinygltf (-ltinygltf), which decodes PNG/JPEG with stb_image.
//
// Errors never cross the extern "C" boundary as exceptions: a malformed file is
// GI_EXIT_DATA with "file: element: what", memory or I/O is GI_EXIT_SYSTEM.
#include <tiny_gltf.h>

#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <new>
#include <set>
#include <string>
#include <vector>

#include "gi_scene.h"

namespace {

// ---- limits and small helpers ------------------------------------------------

const size_t kDefaultLimit = size_t(1) << 28;
size_t g_limit = kDefaultLimit;

const double kPi = 3.14159265358979323846;

struct DataError {
    std::string msg;
};
struct SystemError {
    std::string msg;
};

std::string vstrf(const char *fmt, va_list ap)
{
    va_list ap2;
    va_copy(ap2, ap);
    int n = vsnprintf(nullptr, 0, fmt, ap2);
    va_end(ap2);
    if (n < 0)
        return std::string(fmt);
    std::vector<char> buf(size_t(n) + 1);
    vsnprintf(buf.data(), buf.size(), fmt, ap);
    return std::string(buf.data(), size_t(n));
}

#if defined(__GNUC__)
__attribute__((format(printf, 1, 2)))
#endif
std::string strf(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    std::string s = vstrf(fmt, ap);
    va_end(ap);
    return s;
}

// Throw a data error "place: what".
[[noreturn]]
#if defined(__GNUC__)
__attribute__((format(printf, 2, 3)))
#endif
void fail(const std::string &place, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    std::string s = vstrf(fmt, ap);
    va_end(ap);
    throw DataError{place + ": " + s};
}

// Index `idx` (from element `place`) must name one of n `what`s.
void check_index(int idx, size_t n, const std::string &place, const char *what)
{
    if (idx < 0 || size_t(idx) >= n)
        fail(place, "%s %d does not exist (file has %zu)", what, idx, n);
}

// Optional index: -1 means absent.
void check_opt_index(int idx, size_t n, const std::string &place, const char *what)
{
    if (idx != -1)
        check_index(idx, n, place, what);
}

// Truncate to fit a GI_NAME_MAX buffer without cutting a UTF-8 sequence.
std::string fit_name(const std::string &s, size_t max_bytes = GI_NAME_MAX - 1)
{
    if (s.size() <= max_bytes)
        return s;
    size_t n = max_bytes;
    while (n > 0 && (static_cast<unsigned char>(s[n]) & 0xc0) == 0x80)
        n--;
    return s.substr(0, n);
}

// Make names unique within one set: duplicates get "_2", "_3", ...
struct NameSet {
    std::set<std::string> used;
    size_t renamed = 0;
    std::string take(const std::string &want)
    {
        std::string base = fit_name(want);
        if (used.insert(base).second)
            return base;
        renamed++;
        for (unsigned k = 2;; k++) {
            std::string suffix = strf("_%u", k);
            std::string cand = fit_name(base, GI_NAME_MAX - 1 - suffix.size()) + suffix;
            if (used.insert(cand).second)
                return cand;
        }
    }
};

void copy_name(char dst[GI_NAME_MAX], const std::string &s)
{
    std::string f = fit_name(s);
    memcpy(dst, f.c_str(), f.size() + 1);
}

// ---- small double-precision linear algebra (glTF matrices are column-major) --

struct M4 {
    double m[16];  // m[col * 4 + row]
};

M4 identity()
{
    M4 r{};
    r.m[0] = r.m[5] = r.m[10] = r.m[15] = 1.0;
    return r;
}

M4 mul(const M4 &a, const M4 &b)
{
    M4 r{};
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            double s = 0.0;
            for (int k = 0; k < 4; k++)
                s += a.m[k * 4 + row] * b.m[c * 4 + k];
            r.m[c * 4 + row] = s;
        }
    return r;
}

void xform_point(const M4 &a, const double p[3], double out[3])
{
    for (int r = 0; r < 3; r++)
        out[r] = a.m[r] * p[0] + a.m[4 + r] * p[1] + a.m[8 + r] * p[2] + a.m[12 + r];
}

void xform_dir(const M4 &a, const double d[3], double out[3])
{
    for (int r = 0; r < 3; r++)
        out[r] = a.m[r] * d[0] + a.m[4 + r] * d[1] + a.m[8 + r] * d[2];
}

double det3(const M4 &a)
{
    auto e = [&](int r, int c) { return a.m[c * 4 + r]; };
    return e(0, 0) * (e(1, 1) * e(2, 2) - e(1, 2) * e(2, 1)) -
           e(0, 1) * (e(1, 0) * e(2, 2) - e(1, 2) * e(2, 0)) +
           e(0, 2) * (e(1, 0) * e(2, 1) - e(1, 1) * e(2, 0));
}

// Cofactor matrix of the upper 3x3, times sign(det): maps normals like the
// inverse transpose up to a positive scale (normalised afterwards).
void normal_matrix(const M4 &a, double n[9])
{
    auto e = [&](int r, int c) { return a.m[c * 4 + r]; };
    double c[9];
    c[0] = e(1, 1) * e(2, 2) - e(1, 2) * e(2, 1);
    c[1] = -(e(1, 0) * e(2, 2) - e(1, 2) * e(2, 0));
    c[2] = e(1, 0) * e(2, 1) - e(1, 1) * e(2, 0);
    c[3] = -(e(0, 1) * e(2, 2) - e(0, 2) * e(2, 1));
    c[4] = e(0, 0) * e(2, 2) - e(0, 2) * e(2, 0);
    c[5] = -(e(0, 0) * e(2, 1) - e(0, 1) * e(2, 0));
    c[6] = e(0, 1) * e(1, 2) - e(0, 2) * e(1, 1);
    c[7] = -(e(0, 0) * e(1, 2) - e(0, 2) * e(1, 0));
    c[8] = e(0, 0) * e(1, 1) - e(0, 1) * e(1, 0);
    double s = det3(a) < 0.0 ? -1.0 : 1.0;
    for (int i = 0; i < 9; i++)
        n[i] = s * c[i];  // row-major: n' = C n
}

bool normalize3(double v[3])
{
    double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(l > 0.0) || !std::isfinite(l))
        return false;
    v[0] /= l;
    v[1] /= l;
    v[2] /= l;
    return true;
}

bool all_finite(const std::vector<double> &v)
{
    for (double x : v)
        if (!std::isfinite(x))
            return false;
    return true;
}

// Local transform of a node: matrix, or T * R * S.
M4 node_local(const tinygltf::Node &n, const std::string &place)
{
    if (!n.matrix.empty()) {
        M4 r;
        for (int i = 0; i < 16; i++)
            r.m[i] = n.matrix[size_t(i)];
        return r;
    }
    double t[3] = {0, 0, 0}, s[3] = {1, 1, 1}, q[4] = {0, 0, 0, 1};
    if (!n.translation.empty())
        for (int i = 0; i < 3; i++)
            t[i] = n.translation[size_t(i)];
    if (!n.scale.empty())
        for (int i = 0; i < 3; i++)
            s[i] = n.scale[size_t(i)];
    if (!n.rotation.empty()) {
        double l = 0.0;
        for (int i = 0; i < 4; i++) {
            q[i] = n.rotation[size_t(i)];
            l += q[i] * q[i];
        }
        l = std::sqrt(l);
        if (!(l > 0.0))
            fail(place, "rotation is a zero quaternion");
        for (int i = 0; i < 4; i++)
            q[i] /= l;
    }
    double x = q[0], y = q[1], z = q[2], w = q[3];
    double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                   2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                   2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
    // r is column-major: column c = r[3c..3c+2]
    M4 out{};
    for (int c = 0; c < 3; c++)
        for (int row = 0; row < 3; row++)
            out.m[c * 4 + row] = r[c * 3 + row] * s[c];
    out.m[12] = t[0];
    out.m[13] = t[1];
    out.m[14] = t[2];
    out.m[15] = 1.0;
    return out;
}

// ---- accessor decoding -------------------------------------------------------

int component_size(int ct)
{
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
    }
}

const char *component_name(int ct)
{
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT: return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_INT: return "INT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return "FLOAT";
    default: return "invalid";
    }
}

int type_components(int type)
{
    switch (type) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4: return 4;
    case TINYGLTF_TYPE_MAT2: return 4;
    case TINYGLTF_TYPE_MAT3: return 9;
    case TINYGLTF_TYPE_MAT4: return 16;
    default: return 0;
    }
}

const char *type_name(int type)
{
    switch (type) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    case TINYGLTF_TYPE_MAT2: return "MAT2";
    case TINYGLTF_TYPE_MAT3: return "MAT3";
    case TINYGLTF_TYPE_MAT4: return "MAT4";
    default: return "invalid";
    }
}

const char *mode_name(int mode)
{
    switch (mode) {
    case TINYGLTF_MODE_POINTS: return "POINTS";
    case TINYGLTF_MODE_LINE: return "LINES";
    case TINYGLTF_MODE_LINE_LOOP: return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP: return "LINE_STRIP";
    case TINYGLTF_MODE_TRIANGLES: return "TRIANGLES";
    case TINYGLTF_MODE_TRIANGLE_STRIP: return "TRIANGLE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_FAN: return "TRIANGLE_FAN";
    default: return "invalid";
    }
}

// Little-endian loads (glTF buffers are little-endian whatever the host).
inline uint32_t le16(const unsigned char *p) { return uint32_t(p[0]) | uint32_t(p[1]) << 8; }
inline uint32_t le32(const unsigned char *p)
{
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

inline float load_float(const unsigned char *p, int ct, bool normalized)
{
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        uint32_t b = le32(p);
        float f;
        memcpy(&f, &b, 4);
        return f;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0f : float(p[0]);
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
        float v = float(int8_t(p[0]));
        return normalized ? std::max(v / 127.0f, -1.0f) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        float v = float(le16(p));
        return normalized ? v / 65535.0f : v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
        float v = float(int16_t(uint16_t(le16(p))));
        return normalized ? std::max(v / 32767.0f, -1.0f) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
        double v = le32(p);
        return float(normalized ? v / 4294967295.0 : v);
    }
    case TINYGLTF_COMPONENT_TYPE_INT: {
        double v = double(int32_t(le32(p)));
        return float(normalized ? std::max(v / 2147483647.0, -1.0) : v);
    }
    default: return 0.0f;
    }
}

inline uint32_t load_uint(const unsigned char *p, int ct)
{
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return p[0];
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return le16(p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return le32(p);
    default: return 0;
    }
}

// ---- image header sniffing (dimensions before decoding) ----------------------

// Dimensions of a PNG or JPEG from its header, so that nothing is decoded
// beyond the loader limit. For PNG every chunk length is also checked against
// the data: stb_image trusts them and would allocate what they claim.
// Returns "" on success, else why the image cannot be used.
std::string image_dims(const unsigned char *b, size_t n, int *w, int *h)
{
    static const unsigned char png_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    if (n >= 8 && memcmp(b, png_sig, 8) == 0) {
        if (n < 24 || memcmp(b + 12, "IHDR", 4) != 0)
            return "truncated PNG header";
        uint32_t ww = uint32_t(b[16]) << 24 | uint32_t(b[17]) << 16 | uint32_t(b[18]) << 8 | b[19];
        uint32_t hh = uint32_t(b[20]) << 24 | uint32_t(b[21]) << 16 | uint32_t(b[22]) << 8 | b[23];
        if (ww == 0 || hh == 0 || ww > 0x7fffffffu || hh > 0x7fffffffu)
            return "invalid PNG size";
        for (size_t off = 8; off + 12 <= n;) {
            size_t len = size_t(b[off]) << 24 | size_t(b[off + 1]) << 16 | size_t(b[off + 2]) << 8 |
                         b[off + 3];
            if (len > n - off - 12)
                return strf("corrupt PNG: chunk at byte %zu claims %zu bytes, %zu remain", off, len,
                            n - off - 12);
            if (memcmp(b + off + 4, "IEND", 4) == 0)
                break;
            off += 12 + len;
        }
        *w = int(ww);
        *h = int(hh);
        return "";
    }
    if (n >= 4 && b[0] == 0xff && b[1] == 0xd8) {
        size_t i = 2;
        while (i + 4 <= n) {
            if (b[i] != 0xff)
                return "corrupt JPEG: marker expected";
            unsigned mk = b[i + 1];
            if (mk == 0xff) {  // fill byte
                i++;
                continue;
            }
            if (mk == 0x01 || (mk >= 0xd0 && mk <= 0xd8)) {  // markers without length
                i += 2;
                continue;
            }
            if (mk == 0xd9 || mk == 0xda)  // end of image or scan before a frame header
                return "corrupt JPEG: no frame header";
            size_t len = (size_t(b[i + 2]) << 8) | b[i + 3];
            if (len < 2)
                return "corrupt JPEG: bad segment length";
            if (mk >= 0xc0 && mk <= 0xcf && mk != 0xc4 && mk != 0xc8 && mk != 0xcc) {
                if (i + 9 > n)
                    return "truncated JPEG";
                *h = int((unsigned(b[i + 5]) << 8) | b[i + 6]);
                *w = int((unsigned(b[i + 7]) << 8) | b[i + 8]);
                return *w > 0 && *h > 0 ? "" : "invalid JPEG size";
            }
            i += 2 + len;
        }
        return "truncated JPEG";
    }
    return "not a PNG or JPEG image";
}

float srgb_to_linear(float c)
{
    return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

const float *srgb_table()
{
    static const std::vector<float> table = [] {
        std::vector<float> t(256);
        for (int i = 0; i < 256; i++)
            t[size_t(i)] = float(i <= 10 ? (i / 255.0) / 12.92 : std::pow((i / 255.0 + 0.055) / 1.055, 2.4));
        return t;
    }();
    return table.data();
}

// ---- file system callbacks for tinygltf ----------------------------------------

struct FsCtx {
    bool allowed = true;       // false when loading from memory without base_dir
    std::string prefix;        // paths must start with it (the base directory)
    bool refused = false;      // an external file was asked for but not allowed
    int sys_errno = 0;         // first failure to find or read a file
    std::string sys_path;
};

bool fs_exists(const std::string &path, void *ud)
{
    FsCtx *c = static_cast<FsCtx *>(ud);
    if (!c->allowed) {
        c->refused = true;
        return false;
    }
    // tinygltf also tries the current directory; only the base directory counts.
    if (path.compare(0, c->prefix.size(), c->prefix) != 0)
        return false;
    struct stat sb;
    if (stat(path.c_str(), &sb) != 0) {
        if (!c->sys_errno) {
            c->sys_errno = errno;
            c->sys_path = path;
        }
        return false;
    }
    return true;
}

std::string fs_expand(const std::string &path, void *) { return path; }

bool fs_read(std::vector<unsigned char> *out, std::string *err, const std::string &path, void *ud)
{
    FsCtx *c = static_cast<FsCtx *>(ud);
    FILE *f = fopen(path.c_str(), "rb");
    if (!f) {
        if (!c->sys_errno) {
            c->sys_errno = errno;
            c->sys_path = path;
        }
        if (err)
            *err += strerror(errno);
        return false;
    }
    out->clear();
    unsigned char buf[65536];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, f)) > 0)
        out->insert(out->end(), buf, buf + n);
    bool bad = ferror(f) != 0;
    int e = errno;
    fclose(f);
    if (bad) {
        if (!c->sys_errno) {
            c->sys_errno = e;
            c->sys_path = path;
        }
        if (err)
            *err += strerror(e);
        return false;
    }
    return true;
}

bool fs_write(std::string *err, const std::string &, const std::vector<unsigned char> &, void *)
{
    if (err)
        *err += "writing is not supported";
    return false;
}

// Keep the encoded bytes of URI images; decode later only those used as base
// colour. Images in buffer views are read later from validated ranges, so the
// (unchecked) pointer tinygltf passes for them is never touched.
struct ImageStash {
    std::map<int, std::vector<unsigned char>> raw;
};

bool stash_image(tinygltf::Image *image, const int image_idx, std::string *, std::string *, int,
                 int, const unsigned char *bytes, int size, void *ud)
{
    if (image->bufferView >= 0)
        return true;
    ImageStash *st = static_cast<ImageStash *>(ud);
    if (bytes && size > 0)
        st->raw[image_idx].assign(bytes, bytes + size);
    return true;
}

// ---- safe access to tinygltf::Value (its Get() asserts on a wrong type) -------

const tinygltf::Value *ext_object(const tinygltf::ExtensionMap &ext, const char *name)
{
    auto it = ext.find(name);
    if (it == ext.end() || !it->second.IsObject())
        return nullptr;
    return &it->second;
}

bool value_number(const tinygltf::Value *obj, const char *key, double *out)
{
    if (!obj || !obj->IsObject() || !obj->Has(key))
        return false;
    const tinygltf::Value &v = obj->Get(key);
    if (!v.IsNumber())
        return false;
    *out = v.GetNumberAsDouble();
    return true;
}

bool value_number2(const tinygltf::Value *obj, const char *key, double out[2])
{
    if (!obj || !obj->IsObject() || !obj->Has(key))
        return false;
    const tinygltf::Value &v = obj->Get(key);
    if (!v.IsArray() || v.ArrayLen() != 2 || !v.Get(0).IsNumber() || !v.Get(1).IsNumber())
        return false;
    out[0] = v.Get(0).GetNumberAsDouble();
    out[1] = v.Get(1).GetNumberAsDouble();
    return true;
}

// ---- the loader ----------------------------------------------------------------

struct Loader {
    std::string name;  // file name for messages
    tinygltf::Model m;
    ImageStash stash;

    // output
    std::vector<float> pos, nrm, uv0, uv1;
    std::vector<uint32_t> idx, tri_mat;
    std::vector<gi_material> mats;
    std::vector<int> mat_tex;     // per material: glTF texture index of the base colour, or -1
    std::vector<gi_texture> texs;  // owned rgba until handed over
    std::vector<gi_light> lights;
    std::vector<int> light_src;  // glTF light index of each entry of `lights`
    std::vector<gi_camera> cams;
    std::vector<int> cam_src;    // glTF camera index of each entry of `cams`
    bool need_default = false;

    // warnings
    std::vector<std::string> warnings;
    std::map<int, size_t> skipped_modes;
    std::map<std::string, size_t> ignored_attrs;
    std::map<std::string, size_t> ignored_textures;
    size_t no_position = 0, morph_prims = 0, ortho_cams = 0, alpha_mats = 0;
    size_t leftover_indices = 0, bad_normals = 0, uv_set_unsupported = 0, no_source = 0;
    std::vector<char> light_used, camera_used;
    std::vector<std::vector<char>> prim_seen;

    ~Loader()
    {
        for (gi_texture &t : texs)
            free(t.rgba);
    }

    void validate();
    void validate_accessor(size_t i);
    void traverse();
    void add_primitive(int mesh, int prim, const M4 &world);
    void read_floats(int ai, int ncomp, bool allow_normalized, const std::string &place,
                     std::vector<float> &out);
    void read_indices(int ai, size_t num_vertices, const std::string &place,
                      std::vector<uint32_t> &out);
    void add_light(int node, int light, const M4 &world);
    void add_camera(int node, int cam, const M4 &world);
    void build_materials();
    void build_textures();
    void summarize_warnings();
    gi_scene *emit();
};

void Loader::validate_accessor(size_t i)
{
    const tinygltf::Accessor &a = m.accessors[i];
    std::string place = strf("accessors[%zu]", i);
    int cs = component_size(a.componentType);
    if (cs == 0)
        fail(place, "invalid componentType %d", a.componentType);
    int nc = type_components(a.type);
    if (nc == 0)
        fail(place, "invalid type");
    if (a.count < 1)
        fail(place, "count %zu (must be at least 1)", a.count);
    if (a.count > g_limit)
        fail(place, "count %zu exceeds the loader limit of %zu", a.count, g_limit);
    size_t esize = size_t(cs) * size_t(nc);
    if (a.bufferView != -1) {
        check_index(a.bufferView, m.bufferViews.size(), place + ".bufferView", "bufferView");
        const tinygltf::BufferView &bv = m.bufferViews[size_t(a.bufferView)];
        size_t stride = bv.byteStride ? bv.byteStride : esize;
        if (bv.byteStride && bv.byteStride < esize)
            fail(place, "bufferViews[%d].byteStride %zu is smaller than the element size %zu (%s %s)",
                 a.bufferView, bv.byteStride, esize, type_name(a.type),
                 component_name(a.componentType));
        // offset + stride * (count - 1) + esize <= byteLength, without overflow
        bool ok = a.byteOffset <= bv.byteLength && bv.byteLength - a.byteOffset >= esize &&
                  (a.count - 1) <= (bv.byteLength - a.byteOffset - esize) / stride;
        if (!ok)
            fail(place,
                 "byteOffset %zu + %zu elements of %zu bytes (stride %zu) exceed bufferViews[%d] "
                 "(byteLength %zu)",
                 a.byteOffset, a.count, esize, stride, a.bufferView, bv.byteLength);
    } else if (!a.sparse.isSparse) {
        // zeros: allowed by the spec, but usually a mistake; nothing to check
    }
    if (a.sparse.isSparse) {
        std::string sp = place + ".sparse";
        if (a.sparse.count < 1 || size_t(a.sparse.count) > a.count)
            fail(sp, "count %d must be between 1 and the accessor count %zu", a.sparse.count,
                 a.count);
        size_t sc = size_t(a.sparse.count);
        int ict = a.sparse.indices.componentType;
        if (ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
            ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
            ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
            fail(sp + ".indices", "invalid componentType %d", ict);
        struct {
            const char *what;
            int bv, off;
            size_t size;
        } parts[2] = {{"indices", a.sparse.indices.bufferView, a.sparse.indices.byteOffset,
                       size_t(component_size(ict))},
                      {"values", a.sparse.values.bufferView, a.sparse.values.byteOffset, esize}};
        for (auto &p : parts) {
            std::string pp = sp + "." + p.what;
            check_index(p.bv, m.bufferViews.size(), pp + ".bufferView", "bufferView");
            if (p.off < 0)
                fail(pp, "negative byteOffset %d", p.off);
            const tinygltf::BufferView &bv = m.bufferViews[size_t(p.bv)];
            size_t off = size_t(p.off);
            if (off > bv.byteLength || (bv.byteLength - off) / p.size < sc)
                fail(pp, "byteOffset %zu + %zu elements of %zu bytes exceed bufferViews[%d] "
                         "(byteLength %zu)",
                     off, sc, p.size, p.bv, bv.byteLength);
        }
        const tinygltf::BufferView &ibv = m.bufferViews[size_t(a.sparse.indices.bufferView)];
        const unsigned char *base = m.buffers[size_t(ibv.buffer)].data.data() + ibv.byteOffset +
                                    size_t(a.sparse.indices.byteOffset);
        for (size_t k = 0; k < sc; k++) {
            uint32_t v = load_uint(base + k * size_t(component_size(ict)), ict);
            if (v >= a.count)
                fail(sp + ".indices", "index %u at position %zu is out of range (accessor count %zu)",
                     v, k, a.count);
        }
    }
}

void Loader::validate()
{
    // buffer views: buffer index and byte range
    for (size_t i = 0; i < m.bufferViews.size(); i++) {
        const tinygltf::BufferView &bv = m.bufferViews[i];
        std::string place = strf("bufferViews[%zu]", i);
        check_index(bv.buffer, m.buffers.size(), place + ".buffer", "buffer");
        size_t have = m.buffers[size_t(bv.buffer)].data.size();
        if (bv.byteLength < 1)
            fail(place, "byteLength 0 (must be at least 1)");
        if (bv.byteOffset > have || have - bv.byteOffset < bv.byteLength)
            fail(place, "byteOffset %zu + byteLength %zu exceed buffers[%d] (%zu bytes)",
                 bv.byteOffset, bv.byteLength, bv.buffer, have);
    }
    for (size_t i = 0; i < m.accessors.size(); i++)
        validate_accessor(i);

    // meshes
    for (size_t mi = 0; mi < m.meshes.size(); mi++) {
        const tinygltf::Mesh &mesh = m.meshes[mi];
        for (size_t pi = 0; pi < mesh.primitives.size(); pi++) {
            const tinygltf::Primitive &p = mesh.primitives[pi];
            std::string place = strf("meshes[%zu].primitives[%zu]", mi, pi);
            if (p.mode < 0 || p.mode > 6)
                fail(place, "invalid mode %d", p.mode);
            for (const auto &at : p.attributes)
                check_index(at.second, m.accessors.size(), place + ".attributes." + at.first,
                            "accessor");
            check_opt_index(p.indices, m.accessors.size(), place + ".indices", "accessor");
            check_opt_index(p.material, m.materials.size(), place + ".material", "material");
            for (size_t ti = 0; ti < p.targets.size(); ti++)
                for (const auto &at : p.targets[ti])
                    check_index(at.second, m.accessors.size(),
                                place + strf(".targets[%zu].", ti) + at.first, "accessor");
        }
    }

    // images, samplers, textures
    for (size_t i = 0; i < m.images.size(); i++)
        check_opt_index(m.images[i].bufferView, m.bufferViews.size(), strf("images[%zu].bufferView", i),
                        "bufferView");
    for (size_t i = 0; i < m.samplers.size(); i++) {
        const tinygltf::Sampler &s = m.samplers[i];
        std::string place = strf("samplers[%zu]", i);
        for (int w : {s.wrapS, s.wrapT})
            if (w != TINYGLTF_TEXTURE_WRAP_REPEAT && w != TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE &&
                w != TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT)
                fail(place, "invalid wrap mode %d", w);
        if (s.magFilter != -1 && s.magFilter != TINYGLTF_TEXTURE_FILTER_NEAREST &&
            s.magFilter != TINYGLTF_TEXTURE_FILTER_LINEAR)
            fail(place, "invalid magFilter %d", s.magFilter);
    }
    for (size_t i = 0; i < m.textures.size(); i++) {
        std::string place = strf("textures[%zu]", i);
        check_opt_index(m.textures[i].source, m.images.size(), place + ".source", "image");
        check_opt_index(m.textures[i].sampler, m.samplers.size(), place + ".sampler", "sampler");
    }

    // materials
    for (size_t i = 0; i < m.materials.size(); i++) {
        const tinygltf::Material &mt = m.materials[i];
        std::string place = strf("materials[%zu]", i);
        const tinygltf::PbrMetallicRoughness &pbr = mt.pbrMetallicRoughness;
        check_opt_index(pbr.baseColorTexture.index, m.textures.size(),
                        place + ".pbrMetallicRoughness.baseColorTexture", "texture");
        check_opt_index(pbr.metallicRoughnessTexture.index, m.textures.size(),
                        place + ".pbrMetallicRoughness.metallicRoughnessTexture", "texture");
        check_opt_index(mt.normalTexture.index, m.textures.size(), place + ".normalTexture", "texture");
        check_opt_index(mt.occlusionTexture.index, m.textures.size(), place + ".occlusionTexture",
                        "texture");
        check_opt_index(mt.emissiveTexture.index, m.textures.size(), place + ".emissiveTexture",
                        "texture");
        if (pbr.baseColorFactor.size() != 4 || !all_finite(pbr.baseColorFactor))
            fail(place, "pbrMetallicRoughness.baseColorFactor must be 4 finite numbers");
        if (!std::isfinite(pbr.roughnessFactor) || !std::isfinite(pbr.metallicFactor))
            fail(place, "non-finite roughnessFactor or metallicFactor");
        if (!mt.emissiveFactor.empty() &&
            (mt.emissiveFactor.size() != 3 || !all_finite(mt.emissiveFactor)))
            fail(place, "emissiveFactor must be 3 finite numbers");
        double es = 1.0;
        if (value_number(ext_object(mt.extensions, "KHR_materials_emissive_strength"),
                         "emissiveStrength", &es) &&
            !(std::isfinite(es) && es >= 0.0))
            fail(place, "KHR_materials_emissive_strength.emissiveStrength %g is not a finite "
                        "non-negative number", es);
        for (double c : mt.emissiveFactor)
            if (c < 0.0 || c * es > GI_SCENE_MAX_STRENGTH)
                fail(place, "emission %g (emissiveFactor times emissiveStrength) must be in 0..%g", c * es,
                     GI_SCENE_MAX_STRENGTH);
    }

    // cameras and lights
    for (size_t i = 0; i < m.cameras.size(); i++) {
        const tinygltf::Camera &c = m.cameras[i];
        std::string place = strf("cameras[%zu]", i);
        if (c.type == "perspective") {
            const tinygltf::PerspectiveCamera &p = c.perspective;
            if (!(std::isfinite(p.yfov) && p.yfov > 0.0 && p.yfov < kPi))
                fail(place, "perspective.yfov %g must be in (0, pi)", p.yfov);
            if (!(std::isfinite(p.znear) && p.znear > 0.0))
                fail(place, "perspective.znear %g must be positive", p.znear);
            if (!(std::isfinite(p.aspectRatio) && p.aspectRatio >= 0.0))
                fail(place, "perspective.aspectRatio %g must be positive", p.aspectRatio);
            if (!(std::isfinite(p.zfar) && (p.zfar == 0.0 || p.zfar > p.znear)))
                fail(place, "perspective.zfar %g must be greater than znear", p.zfar);
        } else if (c.type != "orthographic") {
            fail(place, "unknown camera type '%s'", c.type.c_str());
        }
    }
    for (size_t i = 0; i < m.lights.size(); i++) {
        const tinygltf::Light &l = m.lights[i];
        std::string place = strf("extensions.KHR_lights_punctual.lights[%zu]", i);
        if (l.type != "point" && l.type != "spot" && l.type != "directional")
            fail(place, "unknown light type '%s'", l.type.c_str());
        if (!l.color.empty() && (l.color.size() != 3 || !all_finite(l.color)))
            fail(place, "color must be 3 finite numbers");
        for (double c : l.color)
            if (c < 0.0 || c > GI_SCENE_MAX_STRENGTH)
                fail(place, "color %g must be in 0..%g", c, GI_SCENE_MAX_STRENGTH);
        if (!(std::isfinite(l.intensity) && l.intensity >= 0.0 && l.intensity <= GI_SCENE_MAX_STRENGTH))
            fail(place, "intensity %g must be a finite number in 0..%g", l.intensity, GI_SCENE_MAX_STRENGTH);
        if (!(std::isfinite(l.range) && l.range >= 0.0))
            fail(place, "range %g must be non-negative", l.range);
        if (l.type == "spot") {
            double in = l.spot.innerConeAngle, out = l.spot.outerConeAngle;
            if (!(std::isfinite(in) && std::isfinite(out) && in >= 0.0 && in < out &&
                  out <= kPi / 2 + 1e-6))
                fail(place, "spot cone angles inner %g, outer %g must satisfy 0 <= inner < outer "
                            "<= pi/2", in, out);
        }
    }

    // nodes: indices, transforms, one parent at most, no cycles
    std::vector<int> parent(m.nodes.size(), -1);
    for (size_t i = 0; i < m.nodes.size(); i++) {
        const tinygltf::Node &n = m.nodes[i];
        std::string place = strf("nodes[%zu]", i);
        for (size_t k = 0; k < n.children.size(); k++) {
            int c = n.children[k];
            check_index(c, m.nodes.size(), place + strf(".children[%zu]", k), "node");
            if (parent[size_t(c)] != -1)
                fail(place + strf(".children[%zu]", k),
                     "node %d is already a child of node %d (a node may have one parent)", c,
                     parent[size_t(c)]);
            parent[size_t(c)] = int(i);
        }
        check_opt_index(n.mesh, m.meshes.size(), place + ".mesh", "mesh");
        check_opt_index(n.camera, m.cameras.size(), place + ".camera", "camera");
        check_opt_index(n.skin, m.skins.size(), place + ".skin", "skin");
        if (!n.matrix.empty() && (n.matrix.size() != 16 || !all_finite(n.matrix)))
            fail(place, "matrix must be 16 finite numbers");
        if (!n.translation.empty() && (n.translation.size() != 3 || !all_finite(n.translation)))
            fail(place, "translation must be 3 finite numbers");
        if (!n.scale.empty() && (n.scale.size() != 3 || !all_finite(n.scale)))
            fail(place, "scale must be 3 finite numbers");
        if (!n.rotation.empty() && (n.rotation.size() != 4 || !all_finite(n.rotation)))
            fail(place, "rotation must be 4 finite numbers");
        auto it = n.extensions.find("KHR_lights_punctual");
        if (it != n.extensions.end()) {
            std::string lp = place + ".extensions.KHR_lights_punctual.light";
            const tinygltf::Value &v = it->second;
            if (!v.IsObject() || !v.Has("light") || !v.Get("light").IsInt())
                fail(lp, "missing or not an integer");
            check_index(v.Get("light").GetNumberAsInt(), m.lights.size(), lp, "light");
        }
    }
    // cycle detection: walk up the parent chain with a step bound
    for (size_t i = 0; i < m.nodes.size(); i++) {
        size_t steps = 0;
        for (int p = parent[i]; p != -1; p = parent[size_t(p)])
            if (size_t(p) == i || ++steps > m.nodes.size())
                fail(strf("nodes[%zu]", i), "node hierarchy has a cycle through node %zu", i);
    }

    // scenes
    for (size_t i = 0; i < m.scenes.size(); i++) {
        std::set<int> seen;
        for (size_t k = 0; k < m.scenes[i].nodes.size(); k++) {
            int nd = m.scenes[i].nodes[k];
            std::string place = strf("scenes[%zu].nodes[%zu]", i, k);
            check_index(nd, m.nodes.size(), place, "node");
            if (parent[size_t(nd)] != -1)
                fail(place, "node %d is not a root node (it is a child of node %d)", nd,
                     parent[size_t(nd)]);
            if (!seen.insert(nd).second)
                fail(place, "node %d is listed twice", nd);
        }
    }
    check_opt_index(m.defaultScene, m.scenes.size(), "scene", "scene");

    // extensions we cannot do without
    std::set<std::string> supported = {"KHR_lights_punctual", "KHR_texture_transform",
                                       "KHR_materials_emissive_strength"};
    for (const std::string &e : m.extensionsRequired)
        if (!supported.count(e) && e.compare(0, 14, "KHR_materials_") != 0)
            fail("extensionsRequired", "extension '%s' is required but not supported", e.c_str());
}

// Read an accessor as floats: ncomp components (VEC2/VEC3), FLOAT or (if
// allowed) normalized unsigned byte/short, sparse substitutions applied.
void Loader::read_floats(int ai, int ncomp, bool allow_normalized, const std::string &place,
                         std::vector<float> &out)
{
    const tinygltf::Accessor &a = m.accessors[size_t(ai)];
    if (type_components(a.type) != ncomp || a.type == TINYGLTF_TYPE_MAT2)
        fail(place, "accessor %d has type %s, expected %s", ai, type_name(a.type),
             ncomp == 2 ? "VEC2" : "VEC3");
    bool ok = a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
              (allow_normalized && a.normalized &&
               (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT));
    if (!ok)
        fail(place, "accessor %d has component type %s%s, expected FLOAT%s", ai,
             a.normalized ? "normalized " : "", component_name(a.componentType),
             allow_normalized ? " or normalized UNSIGNED_BYTE/UNSIGNED_SHORT" : "");
    size_t nc = size_t(ncomp), cs = size_t(component_size(a.componentType));
    size_t esize = nc * cs;
    out.assign(a.count * nc, 0.0f);
    if (a.bufferView >= 0) {
        const tinygltf::BufferView &bv = m.bufferViews[size_t(a.bufferView)];
        size_t stride = bv.byteStride ? bv.byteStride : esize;
        const unsigned char *base =
            m.buffers[size_t(bv.buffer)].data.data() + bv.byteOffset + a.byteOffset;
        for (size_t i = 0; i < a.count; i++)
            for (size_t c = 0; c < nc; c++)
                out[i * nc + c] = load_float(base + i * stride + c * cs, a.componentType, a.normalized);
    }
    if (a.sparse.isSparse) {
        const tinygltf::BufferView &ibv = m.bufferViews[size_t(a.sparse.indices.bufferView)];
        const tinygltf::BufferView &vbv = m.bufferViews[size_t(a.sparse.values.bufferView)];
        const unsigned char *ib = m.buffers[size_t(ibv.buffer)].data.data() + ibv.byteOffset +
                                  size_t(a.sparse.indices.byteOffset);
        const unsigned char *vb = m.buffers[size_t(vbv.buffer)].data.data() + vbv.byteOffset +
                                  size_t(a.sparse.values.byteOffset);
        int ict = a.sparse.indices.componentType;
        size_t isz = size_t(component_size(ict));
        for (size_t k = 0; k < size_t(a.sparse.count); k++) {
            uint32_t target = load_uint(ib + k * isz, ict);
            if (target >= a.count)
                fail(place, "sparse index %u out of range", target);
            for (size_t c = 0; c < nc; c++)
                out[target * nc + c] = load_float(vb + k * esize + c * cs, a.componentType, a.normalized);
        }
    }
}

void Loader::read_indices(int ai, size_t num_vertices, const std::string &place,
                          std::vector<uint32_t> &out)
{
    const tinygltf::Accessor &a = m.accessors[size_t(ai)];
    if (a.type != TINYGLTF_TYPE_SCALAR)
        fail(place, "accessor %d has type %s, expected SCALAR", ai, type_name(a.type));
    int ct = a.componentType;
    if (ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
        fail(place, "accessor %d has component type %s, expected UNSIGNED_BYTE, UNSIGNED_SHORT or "
                    "UNSIGNED_INT", ai, component_name(ct));
    size_t cs = size_t(component_size(ct));
    out.assign(a.count, 0u);
    if (a.bufferView >= 0) {
        const tinygltf::BufferView &bv = m.bufferViews[size_t(a.bufferView)];
        size_t stride = bv.byteStride ? bv.byteStride : cs;
        const unsigned char *base =
            m.buffers[size_t(bv.buffer)].data.data() + bv.byteOffset + a.byteOffset;
        for (size_t i = 0; i < a.count; i++)
            out[i] = load_uint(base + i * stride, ct);
    }
    if (a.sparse.isSparse) {
        const tinygltf::BufferView &ibv = m.bufferViews[size_t(a.sparse.indices.bufferView)];
        const tinygltf::BufferView &vbv = m.bufferViews[size_t(a.sparse.values.bufferView)];
        const unsigned char *ib = m.buffers[size_t(ibv.buffer)].data.data() + ibv.byteOffset +
                                  size_t(a.sparse.indices.byteOffset);
        const unsigned char *vb = m.buffers[size_t(vbv.buffer)].data.data() + vbv.byteOffset +
                                  size_t(a.sparse.values.byteOffset);
        int ict = a.sparse.indices.componentType;
        size_t isz = size_t(component_size(ict));
        for (size_t k = 0; k < size_t(a.sparse.count); k++) {
            uint32_t target = load_uint(ib + k * isz, ict);
            if (target >= a.count)
                fail(place, "sparse index %u out of range", target);
            out[target] = load_uint(vb + k * cs, ct);
        }
    }
    for (size_t i = 0; i < out.size(); i++)
        if (out[i] >= num_vertices)
            fail(place, "index value %u at position %zu is not below the vertex count %zu", out[i], i,
                 num_vertices);
}

void Loader::add_primitive(int mi, int pi, const M4 &world)
{
    const tinygltf::Primitive &p = m.meshes[size_t(mi)].primitives[size_t(pi)];
    std::string place = strf("meshes[%d].primitives[%d]", mi, pi);
    bool first = !prim_seen[size_t(mi)][size_t(pi)];
    prim_seen[size_t(mi)][size_t(pi)] = 1;

    if (p.mode != TINYGLTF_MODE_TRIANGLES && p.mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
        p.mode != TINYGLTF_MODE_TRIANGLE_FAN) {
        if (first)
            skipped_modes[p.mode]++;
        return;
    }
    auto itp = p.attributes.find("POSITION");
    if (itp == p.attributes.end()) {
        if (first)
            no_position++;
        return;
    }
    if (first) {
        for (const auto &at : p.attributes)
            if (at.first != "POSITION" && at.first != "NORMAL" && at.first != "TEXCOORD_0" &&
                at.first != "TEXCOORD_1")
                ignored_attrs[at.first]++;
        if (!p.targets.empty())
            morph_prims++;
    }

    std::vector<float> P, N, T0, T1;
    read_floats(itp->second, 3, false, place + ".attributes.POSITION", P);
    size_t nv = P.size() / 3;
    for (const auto &at : p.attributes) {
        size_t c = m.accessors[size_t(at.second)].count;
        if (c != nv)
            fail(place + ".attributes." + at.first,
                 "accessor %d has %zu elements but POSITION has %zu", at.second, c, nv);
    }
    auto itn = p.attributes.find("NORMAL");
    if (itn != p.attributes.end())
        read_floats(itn->second, 3, false, place + ".attributes.NORMAL", N);
    auto it0 = p.attributes.find("TEXCOORD_0");
    if (it0 != p.attributes.end())
        read_floats(it0->second, 2, true, place + ".attributes.TEXCOORD_0", T0);
    auto it1 = p.attributes.find("TEXCOORD_1");
    if (it1 != p.attributes.end())
        read_floats(it1->second, 2, true, place + ".attributes.TEXCOORD_1", T1);
    for (size_t i = 0; i < T0.size(); i++)
        if (!std::isfinite(T0[i]))
            fail(place + ".attributes.TEXCOORD_0", "non-finite value at vertex %zu", i / 2);
    for (size_t i = 0; i < T1.size(); i++)
        if (!std::isfinite(T1[i]))
            fail(place + ".attributes.TEXCOORD_1", "non-finite value at vertex %zu", i / 2);

    std::vector<uint32_t> I;
    if (p.indices >= 0) {
        read_indices(p.indices, nv, place + ".indices", I);
    } else {
        I.resize(nv);
        for (size_t i = 0; i < nv; i++)
            I[i] = uint32_t(i);
    }

    // triangles in local vertex numbering
    std::vector<uint32_t> tri;
    size_t n = I.size();
    if (p.mode == TINYGLTF_MODE_TRIANGLES) {
        if (n % 3 && first)
            leftover_indices++;
        tri.assign(I.begin(), I.begin() + ptrdiff_t(n - n % 3));
    } else if (n >= 3) {
        tri.reserve(3 * (n - 2));
        for (size_t i = 0; i + 2 < n; i++) {
            if (p.mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
                // glTF: {v_i, v_(i+1+i%2), v_(i+2-i%2)} keeps the winding of even triangles
                tri.push_back(I[i]);
                tri.push_back(I[i + 1 + i % 2]);
                tri.push_back(I[i + 2 - i % 2]);
            } else {
                tri.push_back(I[i + 1]);
                tri.push_back(I[i + 2]);
                tri.push_back(I[0]);
            }
        }
    }
    size_t nt = tri.size() / 3;

    bool flip = det3(world) < 0.0;
    if (flip)
        for (size_t t = 0; t < nt; t++)
            std::swap(tri[3 * t + 1], tri[3 * t + 2]);

    uint32_t mat;
    if (p.material >= 0) {
        mat = uint32_t(p.material);
    } else {
        need_default = true;
        mat = uint32_t(m.materials.size());
    }

    bool flat = N.empty();
    size_t base = pos.size() / 3;
    size_t add_v = flat ? 3 * nt : nv;
    if (add_v > g_limit - std::min(g_limit, base) || nt > g_limit - std::min(g_limit, tri_mat.size()) ||
        base + add_v > 0xfffffff0u)
        fail(place, "the scene exceeds the loader limit of %zu vertices or triangles", g_limit);

    // world-space vertices
    double nm[9];
    normal_matrix(world, nm);
    auto emit_vertex = [&](size_t v) {
        double lp[3] = {P[3 * v], P[3 * v + 1], P[3 * v + 2]}, wp[3];
        xform_point(world, lp, wp);
        for (int k = 0; k < 3; k++) {
            float f = float(wp[k]);
            if (!std::isfinite(f))
                fail(place + ".attributes.POSITION", "non-finite world position at vertex %zu", v);
            pos.push_back(f);
        }
        uv0.push_back(T0.empty() ? 0.0f : T0[2 * v]);
        uv0.push_back(T0.empty() ? 0.0f : T0[2 * v + 1]);
        const std::vector<float> &u1 = T1.empty() ? T0 : T1;
        uv1.push_back(u1.empty() ? 0.0f : u1[2 * v]);
        uv1.push_back(u1.empty() ? 0.0f : u1[2 * v + 1]);
    };
    pos.reserve(pos.size() + 3 * add_v);
    nrm.reserve(nrm.size() + 3 * add_v);
    uv0.reserve(uv0.size() + 2 * add_v);
    uv1.reserve(uv1.size() + 2 * add_v);
    idx.reserve(idx.size() + 3 * nt);
    tri_mat.reserve(tri_mat.size() + nt);

    if (flat) {
        // glTF: no normals means flat shading, so each corner gets its own vertex
        for (size_t t = 0; t < nt; t++) {
            size_t v0 = pos.size() / 3;
            for (int k = 0; k < 3; k++)
                emit_vertex(tri[3 * t + size_t(k)]);
            const float *a = &pos[3 * v0], *b = a + 3, *c = a + 6;
            double e1[3] = {double(b[0]) - a[0], double(b[1]) - a[1], double(b[2]) - a[2]};
            double e2[3] = {double(c[0]) - a[0], double(c[1]) - a[1], double(c[2]) - a[2]};
            double fn[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                            e1[0] * e2[1] - e1[1] * e2[0]};
            if (!normalize3(fn)) {
                fn[0] = 0.0;  // degenerate triangle: any unit normal will do
                fn[1] = 0.0;
                fn[2] = 1.0;
            }
            for (int k = 0; k < 3; k++)
                for (int j = 0; j < 3; j++)
                    nrm.push_back(float(fn[j]));
            for (int k = 0; k < 3; k++)
                idx.push_back(uint32_t(v0 + size_t(k)));
            tri_mat.push_back(mat);
        }
        return;
    }

    std::vector<char> bad;
    size_t nbad = 0;
    for (size_t v = 0; v < nv; v++) {
        emit_vertex(v);
        double ln[3] = {N[3 * v], N[3 * v + 1], N[3 * v + 2]};
        double wn[3] = {nm[0] * ln[0] + nm[1] * ln[1] + nm[2] * ln[2],
                        nm[3] * ln[0] + nm[4] * ln[1] + nm[5] * ln[2],
                        nm[6] * ln[0] + nm[7] * ln[1] + nm[8] * ln[2]};
        if (!normalize3(wn)) {
            if (bad.empty())
                bad.assign(nv, 0);
            bad[v] = 1;
            nbad++;
            wn[0] = wn[1] = wn[2] = 0.0;
        }
        for (int k = 0; k < 3; k++)
            nrm.push_back(float(wn[k]));
    }
    for (size_t t = 0; t < nt; t++) {
        for (int k = 0; k < 3; k++)
            idx.push_back(uint32_t(base + tri[3 * t + size_t(k)]));
        tri_mat.push_back(mat);
    }
    if (nbad) {
        // zero-length or invalid normals: area-weighted sum of adjacent face normals
        std::vector<double> acc(3 * nv, 0.0);
        for (size_t t = 0; t < nt; t++) {
            const float *a = &pos[3 * (base + tri[3 * t])];
            const float *b = &pos[3 * (base + tri[3 * t + 1])];
            const float *c = &pos[3 * (base + tri[3 * t + 2])];
            double e1[3] = {double(b[0]) - a[0], double(b[1]) - a[1], double(b[2]) - a[2]};
            double e2[3] = {double(c[0]) - a[0], double(c[1]) - a[1], double(c[2]) - a[2]};
            double fn[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                            e1[0] * e2[1] - e1[1] * e2[0]};
            for (int k = 0; k < 3; k++) {
                size_t v = tri[3 * t + size_t(k)];
                if (bad[v])
                    for (int j = 0; j < 3; j++)
                        acc[3 * v + size_t(j)] += fn[j];
            }
        }
        for (size_t v = 0; v < nv; v++) {
            if (!bad[v])
                continue;
            double w[3] = {acc[3 * v], acc[3 * v + 1], acc[3 * v + 2]};
            if (!normalize3(w)) {
                w[0] = 0.0;
                w[1] = 0.0;
                w[2] = 1.0;
            }
            for (int j = 0; j < 3; j++)
                nrm[3 * (base + v) + size_t(j)] = float(w[j]);
        }
        bad_normals += nbad;
    }
}

void Loader::add_light(int node, int li, const M4 &world)
{
    const tinygltf::Light &l = m.lights[size_t(li)];
    light_used[size_t(li)] = 1;
    gi_light g;
    memset(&g, 0, sizeof g);
    g.type = l.type == "spot"          ? GI_LIGHT_SPOT
             : l.type == "directional" ? GI_LIGHT_DIRECTIONAL
                                       : GI_LIGHT_POINT;
    g.enabled = 1;
    for (int k = 0; k < 3; k++)
        g.color[k] = l.color.empty() ? 1.0f : float(l.color[size_t(k)]);
    g.intensity = float(l.intensity);  // glTF: candela (point, spot), lux (directional)
    double o[3] = {0, 0, 0}, wp[3], d[3] = {0, 0, -1}, wd[3];
    xform_point(world, o, wp);
    xform_dir(world, d, wd);
    std::string place = strf("nodes[%d]", node);
    if (!normalize3(wd))
        fail(place, "the transform of light %d has no direction (zero scale)", li);
    for (int k = 0; k < 3; k++) {
        g.position[k] = float(wp[k]);
        g.direction[k] = float(wd[k]);
        if (!std::isfinite(g.position[k]))
            fail(place, "non-finite world position of light %d", li);
    }
    if (g.type == GI_LIGHT_SPOT) {
        g.inner_cone = float(l.spot.innerConeAngle);
        g.outer_cone = float(l.spot.outerConeAngle);
    }
    g.range = float(l.range);
    lights.push_back(g);
    light_src.push_back(li);
}

void Loader::add_camera(int node, int ci, const M4 &world)
{
    const tinygltf::Camera &c = m.cameras[size_t(ci)];
    camera_used[size_t(ci)] = 1;
    if (c.type != "perspective") {
        ortho_cams++;
        return;
    }
    gi_camera g;
    memset(&g, 0, sizeof g);
    double o[3] = {0, 0, 0}, wp[3], fz[3] = {0, 0, -1}, fw[3], uy[3] = {0, 1, 0}, up[3];
    xform_point(world, o, wp);
    xform_dir(world, fz, fw);
    xform_dir(world, uy, up);
    std::string place = strf("nodes[%d]", node);
    if (!normalize3(fw))
        fail(place, "the transform of camera %d has no view direction (zero scale)", ci);
    double dd = up[0] * fw[0] + up[1] * fw[1] + up[2] * fw[2];
    for (int k = 0; k < 3; k++)
        up[k] -= dd * fw[k];
    if (!normalize3(up))
        fail(place, "the transform of camera %d has no up direction", ci);
    for (int k = 0; k < 3; k++) {
        g.position[k] = float(wp[k]);
        g.forward[k] = float(fw[k]);
        g.up[k] = float(up[k]);
        if (!std::isfinite(g.position[k]))
            fail(place, "non-finite world position of camera %d", ci);
    }
    g.yfov = float(c.perspective.yfov);
    g.aspect = float(c.perspective.aspectRatio);
    g.znear = float(c.perspective.znear);
    g.zfar = float(c.perspective.zfar);
    cams.push_back(g);
    cam_src.push_back(ci);
}

void Loader::traverse()
{
    prim_seen.resize(m.meshes.size());
    for (size_t i = 0; i < m.meshes.size(); i++)
        prim_seen[i].assign(m.meshes[i].primitives.size(), 0);
    light_used.assign(m.lights.size(), 0);
    camera_used.assign(m.cameras.size(), 0);

    std::vector<int> roots;
    if (m.defaultScene >= 0) {
        roots = m.scenes[size_t(m.defaultScene)].nodes;
        if (m.scenes.size() > 1)
            warnings.push_back(strf("file has %zu scenes: loaded the default scene %d, ignored the "
                                    "others", m.scenes.size(), m.defaultScene));
    } else if (!m.scenes.empty()) {
        roots = m.scenes[0].nodes;
        if (m.scenes.size() > 1)
            warnings.push_back(strf("file has %zu scenes and no default: loaded scenes[0], ignored "
                                    "the others", m.scenes.size()));
    } else {
        std::vector<char> is_child(m.nodes.size(), 0);
        for (const tinygltf::Node &n : m.nodes)
            for (int c : n.children)
                is_child[size_t(c)] = 1;
        for (size_t i = 0; i < m.nodes.size(); i++)
            if (!is_child[i])
                roots.push_back(int(i));
    }

    // depth first, children in file order; explicit stack (deep hierarchies)
    std::vector<std::pair<int, M4>> stack;
    for (size_t i = roots.size(); i-- > 0;)
        stack.emplace_back(roots[i], identity());
    size_t visited = 0;
    while (!stack.empty()) {
        std::pair<int, M4> top = stack.back();
        stack.pop_back();
        if (++visited > m.nodes.size())  // cannot happen after validate(); belt and braces
            fail("nodes", "node hierarchy is not a tree");
        int ni = top.first;
        const tinygltf::Node &n = m.nodes[size_t(ni)];
        M4 world = mul(top.second, node_local(n, strf("nodes[%d]", ni)));
        if (n.mesh >= 0)
            for (size_t pi = 0; pi < m.meshes[size_t(n.mesh)].primitives.size(); pi++)
                add_primitive(n.mesh, int(pi), world);
        if (n.camera >= 0)
            add_camera(ni, n.camera, world);
        auto it = n.extensions.find("KHR_lights_punctual");
        if (it != n.extensions.end())
            add_light(ni, it->second.Get("light").GetNumberAsInt(), world);
        for (size_t k = n.children.size(); k-- > 0;)
            stack.emplace_back(n.children[k], world);
    }
}

float clamp01(double x) { return float(x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x)); }

void Loader::build_materials()
{
    for (size_t i = 0; i < m.materials.size(); i++) {
        const tinygltf::Material &mt = m.materials[i];
        const tinygltf::PbrMetallicRoughness &pbr = mt.pbrMetallicRoughness;
        gi_material g;
        memset(&g, 0, sizeof g);
        for (int k = 0; k < 3; k++)
            g.base_color[k] = clamp01(pbr.baseColorFactor[size_t(k)]);
        g.roughness = clamp01(pbr.roughnessFactor);
        g.metallic = clamp01(pbr.metallicFactor);
        g.double_sided = mt.doubleSided ? 1 : 0;
        double strength = 1.0;
        value_number(ext_object(mt.extensions, "KHR_materials_emissive_strength"),
                     "emissiveStrength", &strength);
        for (int k = 0; k < 3; k++) {
            double e = mt.emissiveFactor.empty() ? 0.0 : mt.emissiveFactor[size_t(k)];
            g.emission[k] = float(std::max(0.0, e) * strength);
        }
        g.uv_xform[0] = g.uv_xform[4] = 1.0f;
        g.base_color_tex = -1;
        int tex = pbr.baseColorTexture.index;
        if (tex >= 0) {
            int texcoord = pbr.baseColorTexture.texCoord;
            const tinygltf::Value *tt =
                ext_object(pbr.baseColorTexture.extensions, "KHR_texture_transform");
            if (tt) {
                double off[2] = {0, 0}, sc[2] = {1, 1}, rot = 0.0, tc;
                value_number2(tt, "offset", off);
                value_number2(tt, "scale", sc);
                value_number(tt, "rotation", &rot);
                if (value_number(tt, "texCoord", &tc))
                    texcoord = int(std::max(-1.0, std::min(tc, 1e6)));
                if (!(std::isfinite(off[0]) && std::isfinite(off[1]) && std::isfinite(sc[0]) &&
                      std::isfinite(sc[1]) && std::isfinite(rot)))
                    fail(strf("materials[%zu].pbrMetallicRoughness.baseColorTexture", i),
                         "non-finite KHR_texture_transform");
                // glTF: uv' = T * R * S * uv with R = [[cos, sin], [-sin, cos]]
                double c = std::cos(rot), s = std::sin(rot);
                g.uv_xform[0] = float(c * sc[0]);
                g.uv_xform[1] = float(s * sc[1]);
                g.uv_xform[2] = float(off[0]);
                g.uv_xform[3] = float(-s * sc[0]);
                g.uv_xform[4] = float(c * sc[1]);
                g.uv_xform[5] = float(off[1]);
            }
            if (texcoord == 0 || texcoord == 1) {
                g.base_color_uv = texcoord;
            } else {
                uv_set_unsupported++;
                tex = -1;
            }
        }
        mat_tex.push_back(tex);
        if (pbr.metallicRoughnessTexture.index >= 0)
            ignored_textures["metallicRoughnessTexture"]++;
        if (mt.normalTexture.index >= 0)
            ignored_textures["normalTexture"]++;
        if (mt.occlusionTexture.index >= 0)
            ignored_textures["occlusionTexture"]++;
        if (mt.emissiveTexture.index >= 0)
            ignored_textures["emissiveTexture"]++;
        if (mt.alphaMode != "OPAQUE")
            alpha_mats++;
        mats.push_back(g);
    }
}

std::string url_decode(const std::string &s)
{
    std::string r;
    for (size_t i = 0; i < s.size(); i++) {
        if (s[i] == '%' && i + 2 < s.size() && isxdigit((unsigned char)s[i + 1]) &&
            isxdigit((unsigned char)s[i + 2])) {
            r += char(std::stoi(s.substr(i + 1, 2), nullptr, 16));
            i += 2;
        } else {
            r += s[i];
        }
    }
    return r;
}

std::string image_label(const tinygltf::Model &m, int ii)
{
    const tinygltf::Image &im = m.images[size_t(ii)];
    if (!im.uri.empty() && !tinygltf::IsDataURI(im.uri))
        return "'" + url_decode(im.uri) + "'";
    if (!im.name.empty())
        return "'" + im.name + "'";
    return "embedded";
}

struct Decoded {
    float *rgba = nullptr;
    int w = 0, h = 0;
    std::string warning;  // set when the image could not be used
    std::string error;    // data error (limits)
    bool oom = false;
};

void decode_image(const tinygltf::Model &m, const ImageStash &stash, int ii, Decoded &d)
{
    const tinygltf::Image &im = m.images[size_t(ii)];
    std::string label = strf("images[%d] (%s)", ii, image_label(m, ii).c_str());
    const unsigned char *bytes = nullptr;
    size_t len = 0;
    if (im.bufferView >= 0) {
        const tinygltf::BufferView &bv = m.bufferViews[size_t(im.bufferView)];
        bytes = m.buffers[size_t(bv.buffer)].data.data() + bv.byteOffset;
        len = bv.byteLength;
    } else {
        auto it = stash.raw.find(ii);
        if (it != stash.raw.end()) {
            bytes = it->second.data();
            len = it->second.size();
        }
    }
    if (!bytes || len == 0) {
        d.warning = label + ": not loaded (missing or unreadable file); its base colour texture is ignored";
        return;
    }
    int w = 0, h = 0;
    std::string why = image_dims(bytes, len, &w, &h);
    if (!why.empty()) {
        d.warning = label + ": " + why + "; its base colour texture is ignored";
        return;
    }
    if (size_t(w) * size_t(h) > g_limit) {
        d.error = strf("%s: %dx%d texels exceed the loader limit of %zu", label.c_str(), w, h, g_limit);
        return;
    }
    if (len > size_t(0x7fffffff)) {
        d.warning = label + ": encoded image larger than 2 GiB; its base colour texture is ignored";
        return;
    }
    tinygltf::Image img;
    std::string err, warn;
    if (!tinygltf::LoadImageData(&img, ii, &err, &warn, 0, 0, bytes, int(len), nullptr)) {
        while (!err.empty() && (err.back() == '\n' || err.back() == '.'))
            err.pop_back();
        d.warning = label + ": cannot decode (" + err + "); its base colour texture is ignored";
        return;
    }
    size_t bpc = img.bits == 16 ? 2 : 1;
    size_t npx = size_t(img.width) * size_t(img.height);
    if (img.component != 4 || (img.bits != 8 && img.bits != 16) || img.width < 1 || img.height < 1 ||
        npx > g_limit || img.image.size() != npx * 4 * bpc) {
        d.warning = label + ": unexpected decoded layout; its base colour texture is ignored";
        return;
    }
    float *out = static_cast<float *>(malloc(npx * 4 * sizeof(float)));
    if (!out) {
        d.oom = true;
        return;
    }
    const unsigned char *src = img.image.data();
    if (bpc == 1) {
        const float *lut = srgb_table();
        for (size_t i = 0; i < npx; i++) {
            out[4 * i + 0] = lut[src[4 * i + 0]];
            out[4 * i + 1] = lut[src[4 * i + 1]];
            out[4 * i + 2] = lut[src[4 * i + 2]];
            out[4 * i + 3] = src[4 * i + 3] * (1.0f / 255.0f);
        }
    } else {
        for (size_t i = 0; i < npx; i++)
            for (int c = 0; c < 4; c++) {
                uint16_t v;
                memcpy(&v, src + 2 * (4 * i + size_t(c)), 2);  // stb gives host order
                float f = v * (1.0f / 65535.0f);
                out[4 * i + size_t(c)] = c < 3 ? srgb_to_linear(f) : f;
            }
    }
    d.rgba = out;
    d.w = img.width;
    d.h = img.height;
}

void Loader::build_textures()
{
    // glTF textures used as base colour, in order of first use by a material
    std::vector<int> order;
    std::map<int, int> slot;
    for (size_t i = 0; i < mat_tex.size(); i++) {
        int t = mat_tex[i];
        if (t < 0)
            continue;
        if (m.textures[size_t(t)].source < 0) {
            no_source++;
            mat_tex[i] = -1;
            continue;
        }
        if (!slot.count(t)) {
            slot[t] = int(order.size());
            order.push_back(t);
        }
    }
    std::vector<int> images;
    std::map<int, int> image_slot;
    for (int t : order) {
        int src = m.textures[size_t(t)].source;
        if (!image_slot.count(src)) {
            image_slot[src] = int(images.size());
            images.push_back(src);
        }
    }
    std::vector<Decoded> dec(images.size());
    const tinygltf::Model &cm = m;
    const ImageStash &cstash = stash;
#pragma omp parallel for schedule(dynamic, 1) if (images.size() > 1)
    for (size_t k = 0; k < images.size(); k++) {
        try {
            decode_image(cm, cstash, images[k], dec[k]);
        } catch (...) {
            dec[k].oom = true;  // std::bad_alloc is the only exception expected here
        }
    }
    bool oom = false;
    std::string error;
    for (Decoded &d : dec) {
        oom = oom || d.oom;
        if (error.empty() && !d.error.empty())
            error = d.error;
    }
    if (oom || !error.empty()) {
        for (Decoded &d : dec)
            free(d.rgba);
        if (oom)
            throw std::bad_alloc();
        throw DataError{error};
    }
    for (Decoded &d : dec)
        if (!d.warning.empty())
            warnings.push_back(d.warning);

    // one gi_texture per glTF texture whose image decoded; copies for shared images
    std::vector<char> image_taken(images.size(), 0);
    std::map<int, int> gi_index;  // glTF texture -> index in texs
    NameSet names;
    try {
        for (int t : order) {
            const tinygltf::Texture &tx = m.textures[size_t(t)];
            int is = image_slot[tx.source];
            Decoded &d = dec[size_t(is)];
            if (!d.rgba)
                continue;
            gi_texture g;
            memset(&g, 0, sizeof g);
            size_t bytes = size_t(d.w) * size_t(d.h) * 4 * sizeof(float);
            if (!image_taken[size_t(is)]) {
                g.rgba = d.rgba;
                image_taken[size_t(is)] = 1;
            } else {
                g.rgba = static_cast<float *>(malloc(bytes));
                if (!g.rgba)
                    throw std::bad_alloc();
                memcpy(g.rgba, d.rgba, bytes);
            }
            g.width = d.w;
            g.height = d.h;
            texs.push_back(g);  // owns rgba from here on
            gi_texture &gt = texs.back();
            const tinygltf::Image &im = m.images[size_t(tx.source)];
            std::string nm = tx.name;
            if (nm.empty())
                nm = im.name;
            if (nm.empty() && !im.uri.empty() && !tinygltf::IsDataURI(im.uri)) {
                std::string u = url_decode(im.uri);
                size_t sl = u.find_last_of("/\\");
                nm = sl == std::string::npos ? u : u.substr(sl + 1);
            }
            if (nm.empty())
                nm = strf("texture%d", t);
            copy_name(gt.name, names.take(nm));
            gt.wrap_s = gt.wrap_t = GI_WRAP_REPEAT;
            if (tx.sampler >= 0) {
                const tinygltf::Sampler &s = m.samplers[size_t(tx.sampler)];
                auto wrap = [](int w) {
                    return w == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE     ? GI_WRAP_CLAMP
                           : w == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT ? GI_WRAP_MIRROR
                                                                        : GI_WRAP_REPEAT;
                };
                gt.wrap_s = wrap(s.wrapS);
                gt.wrap_t = wrap(s.wrapT);
                gt.nearest = s.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST;
            }
            gi_index[t] = int(texs.size() - 1);
        }
    } catch (...) {
        for (size_t k = 0; k < dec.size(); k++)
            if (!image_taken[k])
                free(dec[k].rgba);
        throw;
    }
    for (size_t k = 0; k < dec.size(); k++)
        if (!image_taken[k])
            free(dec[k].rgba);
    if (names.renamed)
        warnings.push_back(strf("renamed %zu duplicate texture names (suffix _2, _3, ...)",
                                names.renamed));
    for (size_t i = 0; i < mats.size(); i++) {
        auto it = mat_tex[i] >= 0 ? gi_index.find(mat_tex[i]) : gi_index.end();
        mats[i].base_color_tex = it == gi_index.end() ? -1 : it->second;
    }
}

std::string join_counts(const std::map<std::string, size_t> &c)
{
    std::string r;
    for (const auto &kv : c) {
        if (!r.empty())
            r += ", ";
        r += strf("%s (%zu)", kv.first.c_str(), kv.second);
    }
    return r;
}

void Loader::summarize_warnings()
{
    std::set<std::string> supported = {"KHR_lights_punctual", "KHR_texture_transform",
                                       "KHR_materials_emissive_strength"};
    std::string unsup;
    for (const std::string &e : m.extensionsUsed)
        if (!supported.count(e))
            unsup += (unsup.empty() ? "" : ", ") + e;
    if (!unsup.empty())
        warnings.push_back("unsupported extensions ignored: " + unsup);
    for (const std::string &e : m.extensionsRequired)
        if (!supported.count(e))
            warnings.push_back("required extension " + e + " is not supported; its effect is ignored");
    if (!skipped_modes.empty()) {
        size_t total = 0;
        std::string list;
        for (const auto &kv : skipped_modes) {
            total += kv.second;
            list += strf("%s%s (%zu)", list.empty() ? "" : ", ", mode_name(kv.first), kv.second);
        }
        warnings.push_back(strf("skipped %zu non-triangle primitives of mode %s", total, list.c_str()));
    }
    if (no_position)
        warnings.push_back(strf("skipped %zu primitives without POSITION", no_position));
    if (!ignored_attrs.empty())
        warnings.push_back("ignored vertex attributes (primitives): " + join_counts(ignored_attrs));
    if (morph_prims)
        warnings.push_back(strf("ignored morph targets of %zu primitives (base shape used)", morph_prims));
    if (!m.skins.empty())
        warnings.push_back(strf("ignored %zu skins (meshes used in their bind pose)", m.skins.size()));
    if (!m.animations.empty())
        warnings.push_back(strf("ignored %zu animations (static scene at rest pose)", m.animations.size()));
    if (!ignored_textures.empty())
        warnings.push_back("ignored textures (materials): " + join_counts(ignored_textures));
    if (alpha_mats)
        warnings.push_back(strf("ignored alphaMode MASK/BLEND of %zu materials (treated as opaque)",
                                alpha_mats));
    if (uv_set_unsupported)
        warnings.push_back(strf("ignored base colour textures of %zu materials that use TEXCOORD_2 or "
                                "higher", uv_set_unsupported));
    if (no_source)
        warnings.push_back(strf("ignored base colour textures of %zu materials whose texture has no "
                                "PNG/JPEG source", no_source));
    if (ortho_cams)
        warnings.push_back(strf("skipped %zu orthographic cameras (only perspective is supported)",
                                ortho_cams));
    size_t unused_cams = size_t(std::count(camera_used.begin(), camera_used.end(), 0));
    if (unused_cams)
        warnings.push_back(strf("ignored %zu cameras not placed on any node of the scene", unused_cams));
    size_t unused_lights = size_t(std::count(light_used.begin(), light_used.end(), 0));
    if (unused_lights)
        warnings.push_back(strf("ignored %zu lights not placed on any node of the scene", unused_lights));
    if (leftover_indices)
        warnings.push_back(strf("%zu TRIANGLES primitives have an index count not divisible by 3 "
                                "(extra indices ignored)", leftover_indices));
    if (bad_normals)
        warnings.push_back(strf("replaced %zu zero-length or invalid normals by area-weighted face "
                                "normals", bad_normals));
}

gi_scene *Loader::emit()
{
    struct Deleter {
        void operator()(gi_scene *s) const { gi_scene_free(s); }
    };
    std::unique_ptr<gi_scene, Deleter> s(static_cast<gi_scene *>(calloc(1, sizeof(gi_scene))));
    if (!s)
        throw std::bad_alloc();
    std::string p = name;
    if (p.size() >= sizeof s->path)
        p = p.substr(0, sizeof s->path - 1);
    memcpy(s->path, p.c_str(), p.size() + 1);

    auto dup = [](const void *src, size_t bytes) -> void * {
        if (bytes == 0)
            return nullptr;
        void *d = malloc(bytes);
        if (!d)
            throw std::bad_alloc();
        memcpy(d, src, bytes);
        return d;
    };
    s->num_vertices = pos.size() / 3;
    s->positions = static_cast<float *>(dup(pos.data(), pos.size() * sizeof(float)));
    s->normals = static_cast<float *>(dup(nrm.data(), nrm.size() * sizeof(float)));
    s->uv0 = static_cast<float *>(dup(uv0.data(), uv0.size() * sizeof(float)));
    s->uv1 = static_cast<float *>(dup(uv1.data(), uv1.size() * sizeof(float)));
    s->num_triangles = tri_mat.size();
    s->indices = static_cast<uint32_t *>(dup(idx.data(), idx.size() * sizeof(uint32_t)));
    s->tri_material = static_cast<uint32_t *>(dup(tri_mat.data(), tri_mat.size() * sizeof(uint32_t)));

    // materials: file order, then the default one if needed
    NameSet mnames;
    for (size_t i = 0; i < mats.size(); i++) {
        const std::string &n = m.materials[i].name;
        copy_name(mats[i].name, mnames.take(n.empty() ? strf("material%zu", i) : n));
    }
    if (need_default || mats.empty()) {
        gi_material d;
        memset(&d, 0, sizeof d);
        d.base_color[0] = d.base_color[1] = d.base_color[2] = 0.8f;
        d.roughness = 1.0f;
        d.base_color_tex = -1;
        d.uv_xform[0] = d.uv_xform[4] = 1.0f;
        copy_name(d.name, mnames.take("default"));
        mats.push_back(d);
    }
    s->num_materials = mats.size();
    s->materials = static_cast<gi_material *>(dup(mats.data(), mats.size() * sizeof(gi_material)));

    NameSet lnames;
    for (size_t i = 0; i < lights.size(); i++) {
        const std::string &n = m.lights[size_t(light_src[i])].name;
        copy_name(lights[i].name, lnames.take(n.empty() ? strf("light%d", light_src[i]) : n));
    }
    s->num_lights = lights.size();
    s->lights = static_cast<gi_light *>(dup(lights.data(), lights.size() * sizeof(gi_light)));
    NameSet cnames;
    for (size_t i = 0; i < cams.size(); i++) {
        const std::string &n = m.cameras[size_t(cam_src[i])].name;
        copy_name(cams[i].name, cnames.take(n.empty() ? strf("camera%d", cam_src[i]) : n));
    }
    s->num_cameras = cams.size();
    s->cameras = static_cast<gi_camera *>(dup(cams.data(), cams.size() * sizeof(gi_camera)));

    if (mnames.renamed)
        warnings.push_back(strf("renamed %zu duplicate material names (suffix _2, _3, ...)",
                                mnames.renamed));
    if (lnames.renamed)
        warnings.push_back(strf("renamed %zu duplicate light names (suffix _2, _3, ...)",
                                lnames.renamed));
    if (cnames.renamed)
        warnings.push_back(strf("renamed %zu duplicate camera names (suffix _2, _3, ...)",
                                cnames.renamed));

    // textures last: ownership of rgba moves into the scene in one step
    if (!texs.empty()) {
        s->textures = static_cast<gi_texture *>(dup(texs.data(), texs.size() * sizeof(gi_texture)));
        s->num_textures = texs.size();
        texs.clear();
    }

    gi_scene_finalize(s.get());
    for (const std::string &w : warnings)
        gi_scene_warn(s.get(), "%s", w.c_str());
    if (s->num_degenerate)
        gi_scene_warn(s.get(), "%zu degenerate (zero-area) triangles kept in the scene",
                      s->num_degenerate);
    if (s->num_triangles == 0)
        gi_scene_warn(s.get(), "the scene has no triangles");
    return s.release();
}

std::string tidy(std::string s)
{
    // tinygltf messages end in newlines and sometimes periods; join lines with "; "
    std::string r;
    size_t start = 0;
    while (start < s.size()) {
        size_t e = s.find('\n', start);
        std::string line = s.substr(start, e == std::string::npos ? std::string::npos : e - start);
        while (!line.empty() && (line.back() == '.' || line.back() == ' ' || line.back() == '\r'))
            line.pop_back();
        if (!line.empty())
            r += (r.empty() ? "" : "; ") + line;
        if (e == std::string::npos)
            break;
        start = e + 1;
    }
    return r;
}

std::vector<std::string> lines(const std::string &s)
{
    std::vector<std::string> out;
    size_t start = 0;
    while (start < s.size()) {
        size_t e = s.find('\n', start);
        std::string line = tidy(s.substr(start, e == std::string::npos ? std::string::npos : e - start));
        if (!line.empty())
            out.push_back(line);
        if (e == std::string::npos)
            break;
        start = e + 1;
    }
    return out;
}

// Parse, validate and convert. Throws DataError/SystemError/bad_alloc.
gi_scene *load_impl(const unsigned char *data, size_t size, const std::string &name,
                    const char *base_dir)
{
    Loader L;
    L.name = name;
    FsCtx fsc;
    std::string base = base_dir ? base_dir : "";
    fsc.allowed = base_dir != nullptr;
    fsc.prefix = base.empty() ? "" : (base.back() == '/' ? base : base + "/");
    tinygltf::TinyGLTF tg;
    tinygltf::FsCallbacks cb = {fs_exists, fs_expand, fs_read, fs_write, &fsc};
    tg.SetFsCallbacks(cb);
    tg.SetImageLoader(stash_image, &L.stash);

    if (size > 0xffffffffu)
        throw DataError{"file larger than 4 GiB (tinygltf limit)"};
    bool binary = size >= 4 && memcmp(data, "glTF", 4) == 0;
    std::string err, warn;
    bool ok = binary ? tg.LoadBinaryFromMemory(&L.m, &err, &warn, data, unsigned(size), base)
                     : tg.LoadASCIIFromString(&L.m, &err, &warn, reinterpret_cast<const char *>(data),
                                              unsigned(size), base);
    if (!ok) {
        std::string e = tidy(err);
        if (e.empty())
            e = "tinygltf could not parse the file";
        if (fsc.refused)
            throw DataError{"refers to an external file, which is not allowed without a base "
                            "directory (" + e + ")"};
        if (fsc.sys_errno && (e.find("File not found") != std::string::npos ||
                              e.find("File read error") != std::string::npos))
            throw SystemError{"cannot read '" + fsc.sys_path + "': " + strerror(fsc.sys_errno)};
        if (e.find("primitive indices accessor out of bounds") != std::string::npos)
            e = strf("meshes: a primitive's indices accessor does not exist (file has %zu "
                     "accessors; tinygltf: %s)", L.m.accessors.size(), e.c_str());
        throw DataError{e};
    }
    for (const std::string &w : lines(warn))
        L.warnings.push_back("tinygltf: " + w);
    for (const std::string &w : lines(err))
        L.warnings.push_back("tinygltf: " + w);

    L.validate();
    L.build_materials();
    L.traverse();
    L.build_textures();
    L.summarize_warnings();
    return L.emit();
}

int finish(gi_status *st, const std::string &name, int code, const std::string &msg)
{
    return gi_status_set(st, code, "%s: %s", name.c_str(), msg.c_str());
}

// Run f() and turn every exception into a status.
template <class F> int guarded(const std::string &name, gi_status *st, F f)
{
    try {
        f();
        return 0;
    } catch (const DataError &e) {
        return finish(st, name, GI_EXIT_DATA, e.msg);
    } catch (const SystemError &e) {
        return finish(st, name, GI_EXIT_SYSTEM, e.msg);
    } catch (const std::bad_alloc &) {
        return finish(st, name, GI_EXIT_SYSTEM, "out of memory");
    } catch (const std::exception &e) {
        return finish(st, name, GI_EXIT_DATA, std::string("tinygltf: ") + e.what());
    } catch (...) {
        return finish(st, name, GI_EXIT_DATA, "unknown error while loading");
    }
}

}  // namespace

extern "C" int gi_scene_load(const char *path, gi_scene **out, gi_status *st)
{
    if (out)
        *out = nullptr;
    if (!path || !out)
        return gi_status_set(st, GI_EXIT_USAGE, "gi_scene_load: no path or output given");
    std::string name = path;
    return guarded(name, st, [&] {
        FILE *f = fopen(path, "rb");
        if (!f)
            throw SystemError{std::string("cannot open: ") + strerror(errno)};
        std::vector<unsigned char> bytes;
        unsigned char buf[1 << 16];
        size_t n;
        try {
            while ((n = fread(buf, 1, sizeof buf, f)) > 0)
                bytes.insert(bytes.end(), buf, buf + n);
        } catch (...) {
            fclose(f);
            throw;
        }
        int bad = ferror(f), e = errno;
        fclose(f);
        if (bad)
            throw SystemError{std::string("cannot read: ") + strerror(e)};
        size_t sl = name.find_last_of('/');
        std::string dir = sl == std::string::npos ? std::string() : name.substr(0, sl + 1);
        static const unsigned char empty = 0;
        *out = load_impl(bytes.empty() ? &empty : bytes.data(), bytes.size(), name, dir.c_str());
    });
}

extern "C" int gi_scene_load_memory(const void *data, size_t size, const char *name,
                                    const char *base_dir, gi_scene **out, gi_status *st)
{
    if (out)
        *out = nullptr;
    std::string nm = name ? name : "<memory>";
    if (!out || (!data && size))
        return gi_status_set(st, GI_EXIT_USAGE, "gi_scene_load_memory: no data or output given");
    return guarded(nm, st, [&] {
        static const unsigned char empty = 0;
        const unsigned char *d = size ? static_cast<const unsigned char *>(data) : &empty;
        *out = load_impl(d, size, nm, base_dir);
    });
}

extern "C" void gi_scene_set_load_limit(size_t max_elements)
{
    g_limit = max_elements ? max_elements : kDefaultLimit;
}
