// gi_image_oiio.cpp - the C API of gi_image.h implemented on OpenImageIO 2.4.
//
// Every entry point catches all C++ exceptions and turns them into a gi_status.
// Writers create "<path>.tmp.<pid>" with an explicit format name (the temporary
// name has no usable extension), fsync it, then rename it over the target.
#include "gi_image.h"

#include <OpenImageIO/imageio.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace {

// Trim OIIO's multi-line error text to one line for "file: what: message".
std::string one_line(std::string s)
{
    for (char &c : s)
        if (c == '\n' || c == '\r')
            c = ' ';
    while (!s.empty() && s.back() == ' ')
        s.pop_back();
    if (s.empty())
        s = "unknown OpenImageIO error";
    return s;
}

// Check that path names a regular file we can open for reading; GI_EXIT_SYSTEM
// with strerror otherwise, so "missing" and "undecodable" are told apart.
int check_readable(const char *path, gi_status *st)
{
    int fd = open(path, O_RDONLY);
    if (fd < 0)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot open", path);
    struct stat sb;
    int rc = fstat(fd, &sb);
    close(fd);
    if (rc != 0)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot stat", path);
    if (S_ISDIR(sb.st_mode))
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: cannot read: is a directory", path);
    return 0;
}

std::string temp_name(const char *path)
{
    return std::string(path) + ".tmp." + std::to_string(static_cast<long>(getpid()));
}

// fsync the closed temporary file, then rename it over the target.
int commit_temp(const std::string &tmp, const char *path, gi_status *st)
{
    int fd = open(tmp.c_str(), O_RDONLY);
    if (fd < 0) {
        int rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot reopen temporary file", tmp.c_str());
        unlink(tmp.c_str());
        return rc;
    }
    if (fsync(fd) != 0) {
        int rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: fsync", tmp.c_str());
        close(fd);
        unlink(tmp.c_str());
        return rc;
    }
    if (close(fd) != 0) {
        int rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: close", tmp.c_str());
        unlink(tmp.c_str());
        return rc;
    }
    if (rename(tmp.c_str(), path) != 0) {
        int rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot rename '%s' into place", path,
                                 tmp.c_str());
        unlink(tmp.c_str());
        return rc;
    }
    return 0;
}

bool valid_image(const gi_image *im)
{
    return im && im->pixels && im->width > 0 && im->height > 0 && im->channels >= 1 &&
           im->channels <= 4;
}

// Write pixels of `type` (FLOAT or UINT8) with `spec` (format set by the caller)
// through a temporary file. `format` is an OIIO format name ("openexr", "png").
int write_via_temp(const char *path, const char *format, const OIIO::ImageSpec &spec,
                   const void *pixels, gi_status *st)
{
    std::string tmp = temp_name(path);
    auto out = OIIO::ImageOutput::create(format);
    if (!out)
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: no OpenImageIO writer for %s: %s", path,
                             format, one_line(OIIO::geterror()).c_str());
    errno = 0;
    if (!out->open(tmp, spec)) {
        // OIIO reports e.g. "Could not open file" without errno; add it if set.
        int err = errno;
        std::string msg = one_line(out->geterror());
        out.reset();
        unlink(tmp.c_str());
        if (err && msg.find(std::strerror(err)) == std::string::npos) /* (this OIIO often says it) */
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: cannot create '%s': %s (%s)", path,
                                 tmp.c_str(), msg.c_str(), std::strerror(err));
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: cannot create '%s': %s", path, tmp.c_str(),
                             msg.c_str());
    }
    bool ok = out->write_image(spec.format, pixels);
    std::string msg = ok ? std::string() : one_line(out->geterror());
    bool closed = out->close();
    if (ok && !closed)
        msg = one_line(out->geterror());
    out.reset();
    if (!ok || !closed) {
        unlink(tmp.c_str());
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: write failed: %s", path, msg.c_str());
    }
    return commit_temp(tmp, path, st);
}

inline unsigned char quantise(float v)
{
    if (!(v > 0.0f)) // also NaN
        return 0;
    if (v >= 1.0f)
        return 255;
    return static_cast<unsigned char>(std::floor(v * 255.0f + 0.5f));
}

int write_png_u8(const char *path, const std::vector<unsigned char> &bytes, int w, int h, int nc,
                 bool srgb, gi_status *st)
{
    OIIO::ImageSpec spec(w, h, nc, OIIO::TypeDesc::UINT8);
    if (nc == 1)
        spec.channelnames = {"Y"};
    else if (nc == 2)
        spec.channelnames = {"Y", "A"};
    if (nc == 2 || nc == 4) {
        spec.alpha_channel = nc - 1;
        spec.attribute("oiio:UnassociatedAlpha", 1); // write bytes as given, no un-premultiply
    }
    if (srgb)
        spec.attribute("oiio:ColorSpace", "sRGB");
    spec.attribute("png:compressionLevel", 6);
    return write_via_temp(path, "png", spec, bytes.data(), st);
}

} // namespace

extern "C" {

float gi_image_srgb_encode(float x)
{
    if (!(x > 0.0f))
        return 0.0f;
    if (x >= 1.0f)
        return 1.0f;
    if (x <= 0.0031308f)
        return 12.92f * x;
    return 1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f;
}

int gi_image_init(gi_image *im, int w, int h, int channels, gi_status *st)
{
    if (!im)
        return gi_status_set(st, GI_EXIT_SYSTEM, "gi_image_init: null image");
    im->width = im->height = im->channels = 0;
    im->pixels = nullptr;
    if (w <= 0 || h <= 0 || channels < 1 || channels > 4)
        return gi_status_set(st, GI_EXIT_DATA, "image: invalid size %dx%d with %d channels", w, h,
                             channels);
    size_t n = static_cast<size_t>(w) * static_cast<size_t>(h);
    if (n > SIZE_MAX / sizeof(float) / static_cast<size_t>(channels))
        return gi_status_set(st, GI_EXIT_DATA, "image: %dx%d is too large", w, h);
    float *p = static_cast<float *>(std::calloc(n * static_cast<size_t>(channels), sizeof(float)));
    if (!p)
        return gi_status_set(st, GI_EXIT_SYSTEM, "image: out of memory for %dx%d x %d floats", w,
                             h, channels);
    im->width = w;
    im->height = h;
    im->channels = channels;
    im->pixels = p;
    return 0;
}

void gi_image_release(gi_image *im)
{
    if (!im)
        return;
    std::free(im->pixels);
    im->pixels = nullptr;
    im->width = im->height = im->channels = 0;
}

int gi_image_read(const char *path, gi_image *out, gi_status *st)
{
    try {
        if (!path || !out)
            return gi_status_set(st, GI_EXIT_SYSTEM, "gi_image_read: null argument");
        gi_image_release(out);
        int rc = check_readable(path, st);
        if (rc)
            return rc;
        // Keep stored values as they are: PNG/TIFF readers would otherwise
        // premultiply unassociated alpha.
        OIIO::ImageSpec config;
        config.attribute("oiio:UnassociatedAlpha", 1);
        auto in = OIIO::ImageInput::open(path, &config);
        if (!in)
            return gi_status_set(st, GI_EXIT_DATA, "%s: cannot read image: %s", path,
                                 one_line(OIIO::geterror()).c_str());
        const OIIO::ImageSpec &spec = in->spec();
        if (spec.deep)
            return gi_status_set(st, GI_EXIT_DATA, "%s: deep images are not supported", path);
        if (spec.depth > 1)
            return gi_status_set(st, GI_EXIT_DATA, "%s: volume images are not supported", path);
        if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
            return gi_status_set(st, GI_EXIT_DATA, "%s: invalid image size %dx%d with %d channels",
                                 path, spec.width, spec.height, spec.nchannels);
        int nc = spec.nchannels < 4 ? spec.nchannels : 4;
        gi_image im = {0, 0, 0, nullptr};
        rc = gi_image_init(&im, spec.width, spec.height, nc, st);
        if (rc) {
            if (rc == GI_EXIT_DATA)
                gi_status_set(st, rc, "%s: image of %dx%d pixels is too large", path, spec.width,
                              spec.height);
            return rc;
        }
        if (!in->read_image(0, 0, 0, nc, OIIO::TypeDesc::FLOAT, im.pixels)) {
            gi_image_release(&im);
            return gi_status_set(st, GI_EXIT_DATA, "%s: cannot decode pixels: %s", path,
                                 one_line(in->geterror()).c_str());
        }
        in->close();
        *out = im;
        return 0;
    } catch (const std::bad_alloc &) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path ? path : "?");
    } catch (const std::exception &e) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: OpenImageIO: %s", path ? path : "?", e.what());
    } catch (...) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: OpenImageIO: unknown exception",
                             path ? path : "?");
    }
}

int gi_image_write_exr(const char *path, const gi_image *im, const gi_image_meta *meta,
                       size_t nmeta, gi_status *st)
{
    try {
        if (!path || !valid_image(im))
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: gi_image_write_exr: invalid image",
                                 path ? path : "?");
        OIIO::ImageSpec spec(im->width, im->height, im->channels, OIIO::TypeDesc::FLOAT);
        switch (im->channels) {
        case 1: spec.channelnames = {"Y"}; break;
        case 2: spec.channelnames = {"Y", "A"}; spec.alpha_channel = 1; break;
        case 3: spec.channelnames = {"R", "G", "B"}; break;
        default: spec.channelnames = {"R", "G", "B", "A"}; spec.alpha_channel = 3; break;
        }
        spec.attribute("compression", "none");
        for (size_t i = 0; i < nmeta; i++) {
            if (!meta[i].key || !meta[i].key[0] || !meta[i].value)
                return gi_status_set(st, GI_EXIT_SYSTEM, "%s: metadata entry %zu is null", path,
                                     i);
            // OIIO's EXR writer silently drops empty strings; refuse rather than lose one.
            if (!meta[i].value[0])
                return gi_status_set(st, GI_EXIT_DATA,
                                     "%s: metadata 'gi:%s' is empty, which the EXR writer cannot keep",
                                     path, meta[i].key);
            spec.attribute(std::string("gi:") + meta[i].key, meta[i].value);
        }
        return write_via_temp(path, "openexr", spec, im->pixels, st);
    } catch (const std::bad_alloc &) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path ? path : "?");
    } catch (const std::exception &e) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: OpenImageIO: %s", path ? path : "?", e.what());
    } catch (...) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: OpenImageIO: unknown exception",
                             path ? path : "?");
    }
}

int gi_image_read_meta(const char *path, const char *key, char *value, size_t cap, gi_status *st)
{
    try {
        if (!path || !key || !value || cap == 0)
            return gi_status_set(st, GI_EXIT_SYSTEM, "gi_image_read_meta: invalid argument");
        value[0] = '\0';
        int rc = check_readable(path, st);
        if (rc)
            return rc;
        auto in = OIIO::ImageInput::open(path);
        if (!in)
            return gi_status_set(st, GI_EXIT_DATA, "%s: cannot read image: %s", path,
                                 one_line(OIIO::geterror()).c_str());
        std::string name = std::string("gi:") + key;
        const OIIO::ParamValue *p = in->spec().find_attribute(name, OIIO::TypeDesc::STRING);
        if (!p)
            return gi_status_set(st, GI_EXIT_DATA, "%s: no string attribute '%s'", path,
                                 name.c_str());
        OIIO::ustring u = p->get_ustring();
        if (u.size() >= cap)
            return gi_status_set(st, GI_EXIT_DATA, "%s: attribute '%s' is %zu bytes, more than %zu",
                                 path, name.c_str(), u.size(), cap - 1);
        std::memcpy(value, u.c_str(), u.size() + 1);
        return 0;
    } catch (const std::bad_alloc &) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path ? path : "?");
    } catch (const std::exception &e) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: OpenImageIO: %s", path ? path : "?", e.what());
    } catch (...) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: OpenImageIO: unknown exception",
                             path ? path : "?");
    }
}

int gi_image_write_png(const char *path, const gi_image *im, gi_status *st)
{
    try {
        if (!path || !valid_image(im))
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: gi_image_write_png: invalid image",
                                 path ? path : "?");
        size_t n = static_cast<size_t>(im->width) * static_cast<size_t>(im->height) *
                   static_cast<size_t>(im->channels);
        std::vector<unsigned char> bytes(n);
        for (size_t i = 0; i < n; i++)
            bytes[i] = quantise(im->pixels[i]);
        return write_png_u8(path, bytes, im->width, im->height, im->channels, false, st);
    } catch (const std::bad_alloc &) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path ? path : "?");
    } catch (const std::exception &e) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: OpenImageIO: %s", path ? path : "?", e.what());
    } catch (...) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: OpenImageIO: unknown exception",
                             path ? path : "?");
    }
}

int gi_image_write_png_srgb(const char *path, const gi_image *linear, float exposure_scale,
                            gi_status *st)
{
    try {
        if (!path || !valid_image(linear))
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: gi_image_write_png_srgb: invalid image",
                                 path ? path : "?");
        size_t npix = static_cast<size_t>(linear->width) * static_cast<size_t>(linear->height);
        int nc = linear->channels;
        std::vector<unsigned char> bytes(npix * 3);
        for (size_t i = 0; i < npix; i++) {
            const float *px = linear->pixels + i * static_cast<size_t>(nc);
            for (int c = 0; c < 3; c++) {
                float v = nc >= 3 ? px[c] : px[0];
                bytes[i * 3 + static_cast<size_t>(c)] =
                    quantise(gi_image_srgb_encode(v * exposure_scale));
            }
        }
        return write_png_u8(path, bytes, linear->width, linear->height, 3, true, st);
    } catch (const std::bad_alloc &) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path ? path : "?");
    } catch (const std::exception &e) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: OpenImageIO: %s", path ? path : "?", e.what());
    } catch (...) {
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: OpenImageIO: unknown exception",
                             path ? path : "?");
    }
}

} // extern "C"
