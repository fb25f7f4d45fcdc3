/* write.c — choosing an image format and moving bytes safely.
 *
 * Reading opens the file once, sniffs its first bytes (EXR magic, "PF"/"Pf" for PFM, anything
 * else goes to stb_image) and hands the open file to the matching back end. Writing picks the
 * format from the lower-cased extension, writes into "<path>.tmp-<pid>-<n>" beside the target
 * (created with O_EXCL, so concurrent writers never share a temporary), syncs it and renames it
 * over the target; on any failure the temporary is removed and the target is left untouched.
 * Only regular files (or nothing) are replaced: a device, FIFO, folder or symbolic link at the
 * target is refused. Output sets (pn_output_set_*) write several temporaries first and rename
 * them together, so that a run failing on its last output leaves none of them; their
 * temporaries can be removed from a signal handler.
 */
#include "io/image.h"

#include "core/context.h"
#include "core/file.h"

#include <ctype.h>
#include <stdatomic.h>
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
    return pn_image_read_file_limit(path, gamma, 0, out, err);
}

pn_status pn_image_read_file_limit(const char *path, float gamma, uint64_t max_pixels, pn_image *out, pn_err *err) {
    if (out) *out = NULL;
    if (!path || !out) {
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "pn_image_read_file: %s is NULL", path ? "out" : "path");
    }
    if (path[0] == '\0') {
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "image path is empty");
    }

    /* Only a regular file within the input limit: devices and FIFOs cannot be sniffed and
     * re-read (EXR needs random access), and must not block or grow without bound. */
    pn_err why;
    pn_err_init(&why);
    pn_image_limits limits = {0, max_pixels ? max_pixels : PN_IMAGE_MAX_PIXELS_DEFAULT};
    FILE *file = pn_file_open_regular(path, PN_INPUT_FILE_MAX_BYTES, &limits.file_size, &why);
    if (!file) return pn_err_set(err, why.status, "%s: %s", path, why.message);

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
        status = pn_exr_read(file, path, &limits, out, err);
    } else if (is_pfm) {
        status = pn_pfm_read(file, path, &limits, out, err);
    } else if (by_name == PN_FORMAT_EXR) {
        status = pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid EXR file: wrong magic number", path);
    } else if (by_name == PN_FORMAT_PFM) {
        status =
            pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid PFM file: header does not start with PF or Pf", path);
    } else {
        status = pn_ldr_read(file, path, gamma, &limits, out, err);
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

/* Output sets. A slot's temporary name is published (atomically) from just before the
 * temporary is created until it is renamed or removed, so that pn_output_set_discard_temporaries
 * can remove it from a signal handler at any moment; a name is never edited while published. */
#define PN_OUTPUT_SET_MAX 64

struct pn_output_set_s {
    _Atomic(char *) temporary[PN_OUTPUT_SET_MAX];
    char *target[PN_OUTPUT_SET_MAX];
    atomic_int count;
};

/* Refuses to replace anything but a regular file (or nothing): renaming over a device such as
 * /dev/full, a FIFO, a folder or a symbolic link would destroy it rather than write through it. */
static pn_status pn_check_replaceable(const char *path, pn_err *err) {
    struct stat st;
    if (lstat(path, &st) != 0)
        return errno == ENOENT ? PN_OK : pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(errno));
    if (S_ISREG(st.st_mode)) return PN_OK;
    return pn_err_set(err, PN_ERROR_IO, "%s: is %s; only a regular file is replaced by an output", path,
                      pn_file_type_name((unsigned)st.st_mode));
}

/* Creates a fresh temporary file next to `path` and publishes its name in `slot`. Returns the
 * descriptor, or -1 with errno set (and the slot empty). The name is "<path>.tmp-<pid>-<n>" with
 * the first free n; when that is too long for the file system, ".pn-tmp-<pid>-<n>" in the same
 * folder. O_EXCL: concurrent writers never share a temporary, and a planted symbolic link is
 * never followed. */
static int pn_create_temporary(const char *path, _Atomic(char *) *slot) {
    size_t size = strlen(path) + 64;
    const char *slash = strrchr(path, '/');
    int dir_len = slash ? (int)(slash - path + 1) : 0;
    long pid = (long)getpid();
    int short_form = 0;
    for (unsigned attempt = 0; attempt < 10000; attempt++) {
        /* A fresh buffer per attempt: a published name is never rewritten. */
        char *name = malloc(size);
        if (!name) {
            errno = ENOMEM;
            return -1;
        }
        if (short_form) {
            snprintf(name, size, "%.*s.pn-tmp-%ld-%u", dir_len, path, pid, attempt);
        } else {
            snprintf(name, size, "%s.tmp-%ld-%u", path, pid, attempt);
        }
        atomic_store(slot, name);
        int fd = open(name, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd >= 0) return fd;
        int e = errno;
        atomic_store(slot, NULL);
        free(name);
        errno = e;
        if (e == ENAMETOOLONG && !short_form) {
            short_form = 1;
            attempt = 0;
            continue;
        }
        if (e != EEXIST) break;
    }
    return -1;
}

/* Removes the slot's temporary (if any) and empties the slot. */
static void pn_output_slot_discard(_Atomic(char *) *slot) {
    char *name = atomic_exchange(slot, NULL);
    if (name) {
        unlink(name);
        free(name);
    }
}

static void pn_output_set_init(struct pn_output_set_s *set) {
    for (int i = 0; i < PN_OUTPUT_SET_MAX; i++) {
        atomic_init(&set->temporary[i], NULL);
        set->target[i] = NULL;
    }
    atomic_init(&set->count, 0);
}

static void pn_output_set_release(struct pn_output_set_s *set) {
    int count = atomic_load(&set->count);
    for (int i = 0; i < count; i++) {
        pn_output_slot_discard(&set->temporary[i]);
        free(set->target[i]);
        set->target[i] = NULL;
    }
    atomic_store(&set->count, 0);
}

/* Writes one complete, synced temporary beside `path` into the set. */
static pn_status pn_output_set_add(struct pn_output_set_s *set, const char *path, pn_write_fn write_to, void *user,
                                   pn_err *err) {
    if (!path || path[0] == '\0') return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "file path is empty");
    int slot = atomic_load(&set->count);
    if (slot >= PN_OUTPUT_SET_MAX)
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "%s: more than %d outputs in one set", path,
                          PN_OUTPUT_SET_MAX);
    pn_status status = pn_check_replaceable(path, err);
    if (status != PN_OK) return status;
    size_t len = strlen(path);
    char *target = malloc(len + 1);
    if (!target) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    memcpy(target, path, len + 1);
    set->target[slot] = target;
    atomic_store(&set->count, slot + 1);

    int fd = pn_create_temporary(path, &set->temporary[slot]);
    if (fd < 0) return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(errno));
    FILE *file = fdopen(fd, "wb");
    if (!file) {
        int e = errno;
        close(fd);
        pn_output_slot_discard(&set->temporary[slot]);
        return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(e));
    }

    status = write_to(user, file, path, err);

    /* Flush, sync and close even after a failure so the descriptor is released. */
    int io_errno = 0;
    if (fflush(file) != 0 || ferror(file)) io_errno = errno ? errno : EIO;
    if (status == PN_OK && io_errno == 0 && fsync(fileno(file)) != 0 && errno != EINVAL && errno != EROFS) {
        io_errno = errno;
    }
    if (fclose(file) != 0 && io_errno == 0) io_errno = errno ? errno : EIO;
    if (status == PN_OK && io_errno != 0) status = pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(io_errno));
    if (status != PN_OK) pn_output_slot_discard(&set->temporary[slot]);
    return status;
}

/* Renames every temporary over its target, in the order they were added; stops at the first
 * failure, leaving the remaining temporaries for pn_output_set_release to remove. */
static pn_status pn_output_set_rename_all(struct pn_output_set_s *set, pn_err *err) {
    int count = atomic_load(&set->count);
    for (int i = 0; i < count; i++) {
        char *tmp = atomic_load(&set->temporary[i]);
        if (!tmp) continue;
        pn_status status = pn_check_replaceable(set->target[i], err);
        if (status != PN_OK) return status;
        if (rename(tmp, set->target[i]) != 0)
            return pn_err_set(err, PN_ERROR_IO, "%s: %s", set->target[i], strerror(errno));
        atomic_store(&set->temporary[i], NULL);
        free(tmp);
    }
    return PN_OK;
}

/* The one atomic-write routine of the project for a single file: a set of one. */
pn_status pn_write_atomic(const char *path, pn_write_fn write_to, void *user, pn_err *err) {
    struct pn_output_set_s set;
    pn_output_set_init(&set);
    pn_status status = pn_output_set_add(&set, path, write_to, user, err);
    if (status == PN_OK) status = pn_output_set_rename_all(&set, err);
    pn_output_set_release(&set);
    return status;
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

/* Checks the image and picks the format from the extension of `path`. */
static pn_status pn_image_write_job_make(pn_image image, const char *path, float exposure, image_write_job *job,
                                         pn_err *err) {
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
    *job = (image_write_job){image, format, exposure};
    return PN_OK;
}

pn_status pn_image_write_file(pn_image image, const char *path, float exposure, pn_err *err) {
    image_write_job job;
    pn_status status = pn_image_write_job_make(image, path, exposure, &job, err);
    return status == PN_OK ? pn_write_atomic(path, write_image_to, &job, err) : status;
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

/* ---------------------------------------------------------------------------------------- */
/* Public output sets */

pn_output_set pn_output_set_new(void) {
    struct pn_output_set_s *set = malloc(sizeof *set);
    if (set) pn_output_set_init(set);
    return set;
}

void pn_output_set_free(pn_output_set set) {
    if (!set) return;
    pn_output_set_release(set);
    free(set);
}

void pn_output_set_discard_temporaries(pn_output_set set) {
    if (!set) return;
    /* Async-signal-safe: atomic loads and unlink only; the names are freed later. */
    int count = atomic_load(&set->count);
    for (int i = 0; i < count && i < PN_OUTPUT_SET_MAX; i++) {
        char *name = atomic_load(&set->temporary[i]);
        if (name) unlink(name);
    }
}

pn_status pn_output_set_add_image(pn_context ctx, pn_output_set set, pn_image image, const char *path, float exposure) {
    pn_err err;
    pn_err_init(&err);
    image_write_job job;
    pn_status status = set ? pn_image_write_job_make(image, path, exposure, &job, &err)
                           : pn_err_set(&err, PN_ERROR_INVALID_ARGUMENT, "pn_output_set_add_image: set is NULL");
    if (status == PN_OK) status = pn_output_set_add(set, path, write_image_to, &job, &err);
    return status == PN_OK ? PN_OK : pn_context_fail_from(ctx, &err);
}

pn_status pn_output_set_add_file(pn_context ctx, pn_output_set set, const char *path, const void *data, size_t size) {
    pn_err err;
    pn_err_init(&err);
    bytes_job job = {data, size};
    pn_status status = set && path && (data || !size)
                           ? pn_output_set_add(set, path, write_bytes_to, &job, &err)
                           : pn_err_set(&err, PN_ERROR_INVALID_ARGUMENT, "pn_output_set_add_file: NULL argument");
    return status == PN_OK ? PN_OK : pn_context_fail_from(ctx, &err);
}

pn_status pn_output_set_commit(pn_context ctx, pn_output_set set) {
    pn_err err;
    pn_err_init(&err);
    pn_status status = set ? pn_output_set_rename_all(set, &err)
                           : pn_err_set(&err, PN_ERROR_INVALID_ARGUMENT, "pn_output_set_commit: set is NULL");
    return status == PN_OK ? PN_OK : pn_context_fail_from(ctx, &err);
}
