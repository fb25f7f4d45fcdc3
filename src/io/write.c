/* write.c — choosing an image format and moving bytes safely.
 *
 * Reading opens the file once, sniffs its first bytes (EXR magic, "PF"/"Pf" for PFM, anything
 * else goes to stb_image) and hands the open file to the matching back end. Writing picks the
 * format from the lower-cased extension, writes into "<path>.tmp-<pid>-<n>" beside the target
 * (created with O_EXCL, so concurrent writers never share a temporary), syncs it and renames it
 * over the target; on any failure the temporary is removed and the target is left untouched.
 */
#include "io/image.h"

#include "core/context.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

typedef enum pn_image_format { PN_FORMAT_UNKNOWN = 0, PN_FORMAT_EXR, PN_FORMAT_PFM, PN_FORMAT_PNG } pn_image_format;

/* Copies the lower-cased extension of the last path component (".exr", ...) into `ext`; an
 * empty string when there is none or it is implausibly long. */
static void pn_path_extension(const char *path, char *ext, size_t ext_size) {
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    ext[0] = '\0';
    if (!dot || dot == base) return;
    size_t len = strlen(dot);
    if (len + 1 > ext_size) return;
    for (size_t i = 0; i <= len; i++) ext[i] = (char)tolower((unsigned char)dot[i]);
}

static pn_image_format pn_format_from_extension(const char *ext) {
    if (strcmp(ext, ".exr") == 0) return PN_FORMAT_EXR;
    if (strcmp(ext, ".pfm") == 0) return PN_FORMAT_PFM;
    if (strcmp(ext, ".png") == 0) return PN_FORMAT_PNG;
    return PN_FORMAT_UNKNOWN;
}

/* ---------------------------------------------------------------------------------------- */
/* Reading */

pn_status pn_image_read_file(const char *path, float gamma, pn_image *out, pn_err *err) {
    if (out) *out = NULL;
    if (!path || !out) {
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "pn_image_read_file: %s is NULL", path ? "out" : "path");
    }
    if (path[0] == '\0') {
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "image path is empty");
    }

    FILE *file = fopen(path, "rb");
    if (!file) return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(errno));

    struct stat st;
    if (fstat(fileno(file), &st) != 0) {
        int e = errno;
        fclose(file);
        return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(e));
    }
    if (S_ISDIR(st.st_mode)) {
        fclose(file);
        return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(EISDIR));
    }
    if (!S_ISREG(st.st_mode)) {
        /* Devices and pipes cannot be sniffed and re-read; EXR needs random access. */
        fclose(file);
        return pn_err_set(err, PN_ERROR_IO, "%s: not a regular file", path);
    }

    unsigned char magic[4] = {0, 0, 0, 0};
    size_t got = fread(magic, 1, sizeof magic, file);
    if (ferror(file)) {
        int e = errno;
        fclose(file);
        return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(e ? e : EIO));
    }
    if (fseek(file, 0, SEEK_SET) != 0) {
        int e = errno;
        fclose(file);
        return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(e));
    }

    char ext[16];
    pn_path_extension(path, ext, sizeof ext);
    pn_image_format by_name = pn_format_from_extension(ext);

    int is_exr = got >= 4 && magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01;
    int is_pfm = got >= 3 && magic[0] == 'P' && (magic[1] == 'F' || magic[1] == 'f') && isspace(magic[2]);

    pn_status status;
    if (got == 0) {
        status = pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid image file: file is empty", path);
    } else if (is_exr) {
        status = pn_exr_read(file, path, out, err);
    } else if (is_pfm) {
        status = pn_pfm_read(file, path, out, err);
    } else if (by_name == PN_FORMAT_EXR) {
        status = pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid EXR file: wrong magic number", path);
    } else if (by_name == PN_FORMAT_PFM) {
        status =
            pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid PFM file: header does not start with PF or Pf", path);
    } else {
        status = pn_ldr_read(file, path, gamma, out, err);
    }
    fclose(file);

    if (status == PN_OK && !*out) {
        status = pn_err_set(err, PN_ERROR_INTERNAL, "%s: reader returned no image", path);
    }
    if (status != PN_OK && *out) {
        pn_image_free(*out);
        *out = NULL;
    }
    return status;
}

/* ---------------------------------------------------------------------------------------- */
/* Writing */

/* Creates a fresh temporary file next to `path`; stores its name in `tmp` (malloc'd). Returns
 * the descriptor, or -1 with errno set. The name is "<path>.tmp-<pid>-<n>" with the first free
 * n; when that is too long for the file system, ".pn-tmp-<pid>-<n>" in the same folder. */
static int pn_create_temporary(const char *path, char **tmp) {
    size_t size = strlen(path) + 64;
    char *name = malloc(size);
    if (!name) {
        errno = ENOMEM;
        return -1;
    }
    const char *slash = strrchr(path, '/');
    int dir_len = slash ? (int)(slash - path + 1) : 0;
    long pid = (long)getpid();
    int short_form = 0;
    for (unsigned attempt = 0; attempt < 10000; attempt++) {
        if (short_form) {
            snprintf(name, size, "%.*s.pn-tmp-%ld-%u", dir_len, path, pid, attempt);
        } else {
            snprintf(name, size, "%s.tmp-%ld-%u", path, pid, attempt);
        }
        int fd = open(name, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd >= 0) {
            *tmp = name;
            return fd;
        }
        if (errno == ENAMETOOLONG && !short_form) {
            short_form = 1;
            attempt = 0;
            continue;
        }
        if (errno != EEXIST) break;
    }
    int e = errno;
    free(name);
    errno = e;
    return -1;
}

typedef struct image_write_job {
    pn_image image;
    pn_image_format format;
    float exposure;
} image_write_job;

static pn_status write_image_to(void *user, FILE *file, const char *path, pn_err *err) {
    const image_write_job *job = user;
    switch (job->format) {
    case PN_FORMAT_EXR: return pn_exr_write(job->image, file, path, err);
    case PN_FORMAT_PFM: return pn_pfm_write(job->image, file, path, err);
    case PN_FORMAT_PNG: return pn_png_write(job->image, job->exposure, file, path, err);
    default: return pn_err_set(err, PN_ERROR_INTERNAL, "%s: unhandled format", path);
    }
}

pn_status pn_image_write_file(pn_image image, const char *path, float exposure, pn_err *err) {
    if (!image || !path) {
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "pn_image_write_file: %s is NULL", path ? "image" : "path");
    }
    if (path[0] == '\0') {
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "image path is empty");
    }
    if (image->layer_count < 1 || image->layers[0].channels != 3 || image->width <= 0 || image->height <= 0) {
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "%s: image has no 3-channel beauty layer", path);
    }

    char ext[16];
    pn_path_extension(path, ext, sizeof ext);
    pn_image_format format = pn_format_from_extension(ext);
    if (format == PN_FORMAT_UNKNOWN) {
        const char *slash = strrchr(path, '/');
        const char *dot = strrchr(slash ? slash + 1 : path, '.');
        if (!dot) {
            return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "%s: no file extension (use .exr, .pfm or .png)", path);
        }
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "%s: unknown image format '%s' (use .exr, .pfm or .png)",
                          path, dot);
    }

    image_write_job job = {image, format, exposure};
    return pn_write_atomic(path, write_image_to, &job, err);
}

/* The one atomic-write routine of the project: every file penumbra writes (images, the CLI's
 * statistics JSON through pn_file_write) goes through it. */
pn_status pn_write_atomic(const char *path, pn_write_fn write_to, void *user, pn_err *err) {
    if (!path || path[0] == '\0') return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "file path is empty");
    char *tmp = NULL;
    int fd = pn_create_temporary(path, &tmp);
    if (fd < 0) return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(errno));

    FILE *file = fdopen(fd, "wb");
    if (!file) {
        int e = errno;
        close(fd);
        unlink(tmp);
        free(tmp);
        return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(e));
    }

    pn_status status = write_to(user, file, path, err);

    /* Flush, sync and close even after a failure so the descriptor is released. */
    int io_errno = 0;
    if (fflush(file) != 0 || ferror(file)) io_errno = errno ? errno : EIO;
    if (status == PN_OK && io_errno == 0 && fsync(fileno(file)) != 0 && errno != EINVAL && errno != EROFS) {
        io_errno = errno;
    }
    if (fclose(file) != 0 && io_errno == 0) io_errno = errno ? errno : EIO;

    if (status == PN_OK && io_errno != 0) {
        status = pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(io_errno));
    }
    if (status == PN_OK && rename(tmp, path) != 0) {
        status = pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(errno));
    }
    if (status != PN_OK) unlink(tmp);
    free(tmp);
    return status;
}

typedef struct bytes_job {
    const void *data;
    size_t size;
} bytes_job;

static pn_status write_bytes_to(void *user, FILE *file, const char *path, pn_err *err) {
    const bytes_job *job = user;
    if (job->size && fwrite(job->data, 1, job->size, file) != job->size)
        return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(errno ? errno : EIO));
    return PN_OK;
}

pn_status pn_file_write(pn_context ctx, const char *path, const void *data, size_t size) {
    pn_err err;
    pn_err_init(&err);
    if (!path || (!data && size)) {
        pn_err_set(&err, PN_ERROR_INVALID_ARGUMENT, "pn_file_write: NULL argument");
        return pn_context_fail_from(ctx, &err);
    }
    bytes_job job = {data, size};
    pn_status status = pn_write_atomic(path, write_bytes_to, &job, &err);
    return status == PN_OK ? PN_OK : pn_context_fail_from(ctx, &err);
}
