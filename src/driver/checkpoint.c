/* checkpoint.c — `--checkpoint FILE`: the finished tiles of a render, recorded as it goes, so
 * that the same command after a crash, a kill or a Ctrl-C resumes and gives the identical image
 * (docs/distributed.md).
 *
 * The file is an append-only log in the machine's byte order (a checkpoint is resumed on the
 * machine, or the cluster, that wrote it):
 *   header (64 bytes): magic "PNCKPT01", version, header size, the render key (pn_render_key:
 *     scene contents, options, seed), the window, the tile side and count, the size of one
 *     pixel estimate, and an FNV-1a checksum of the bytes before it;
 *   records: magic "TILE", the tile index, the payload size, an FNV-1a checksum of index, size
 *     and payload, then the tile's pixel estimates (pn_pixel_estimate, packed row by row).
 * A new file is created with O_EXCL (two renders never write one file) and its header synced
 * with the folder; each record is one write() followed by fdatasync, so a kill leaves at most
 * one torn record at the end, which resuming drops (the file is truncated there). Anything else
 * that does not check out (another render's key, another layout, a record whose checksum fails)
 * is refused with an error naming the file: tiles are never silently mixed. */
#include "driver/tiles.h"

#include "core/file.h"

#include "integrators/registry.h"
#include "scene/scene.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define CKPT_MAGIC "PNCKPT01"
#define CKPT_VERSION 1u
#define TILE_MAGIC 0x454c4954u /* "TILE" */

/* ---- the render key ---------------------------------------------------------------------- */

typedef struct fnv {
    uint64_t h;
} fnv;

static void fnv_bytes(fnv *f, const void *data, size_t n) {
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) {
        f->h ^= p[i];
        f->h *= 0x100000001b3ull;
    }
}
static void fnv_u64(fnv *f, uint64_t v) {
    fnv_bytes(f, &v, sizeof v);
}
static void fnv_f32(fnv *f, const float *v, size_t n) {
    fnv_bytes(f, v, n * sizeof *v);
}
static void fnv_str(fnv *f, const char *s) {
    fnv_u64(f, s ? strlen(s) : 0);
    if (s) fnv_bytes(f, s, strlen(s));
}
static uint64_t fnv_of(const void *data, size_t n) {
    fnv f = {0xcbf29ce484222325ull};
    fnv_bytes(&f, data, n);
    return f.h;
}

/* The scene file's own bytes (camera, lights, material parameters; included files show
 * through what they produced below). */
static void hash_file(fnv *f, const char *path) {
    FILE *file = path ? fopen(path, "rb") : NULL;
    if (!file) return;
    char buf[65536];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, file)) > 0) fnv_bytes(f, buf, n);
    fclose(file);
}

static void hash_scene(fnv *f, const struct pn_scene_s *s) {
    hash_file(f, s->path);
    fnv_u64(f, (uint64_t)s->mesh_count);
    for (int i = 0; i < s->mesh_count; i++) {
        const pn_mesh *m = &s->meshes[i];
        fnv_u64(f, ((uint64_t)m->vertex_count << 32) | m->triangle_count);
        fnv_f32(f, m->positions, 3 * (size_t)m->vertex_count);
        if (m->normals) fnv_f32(f, m->normals, 3 * (size_t)m->vertex_count);
        if (m->uvs) fnv_f32(f, m->uvs, 2 * (size_t)m->vertex_count);
        fnv_bytes(f, m->indices, 3 * (size_t)m->triangle_count * sizeof *m->indices);
        fnv_u64(f, ((uint64_t)(uint32_t)m->material << 32) | (uint32_t)m->emission);
        fnv_u64(f, (uint64_t)m->flip_normals);
    }
    for (int i = 0; i < s->sphere_count; i++) {
        fnv_f32(f, &s->spheres[i].center.x, 1);
        fnv_f32(f, &s->spheres[i].center.y, 1);
        fnv_f32(f, &s->spheres[i].center.z, 1);
        fnv_f32(f, &s->spheres[i].radius, 1);
    }
    for (int i = 0; i < s->instance_count; i++) fnv_bytes(f, &s->instances[i].world_from_object, sizeof(mat4));
    for (int i = 0; i < s->emission_count; i++) {
        fnv_f32(f, &s->emissions[i].radiance.x, 1);
        fnv_f32(f, &s->emissions[i].radiance.y, 1);
        fnv_f32(f, &s->emissions[i].radiance.z, 1);
        fnv_u64(f, (uint64_t)s->emissions[i].two_sided | (uint64_t)s->emissions[i].per_shape << 8);
    }
    for (int i = 0; i < s->light_def_count; i++) {
        const pn_light_def *l = &s->light_defs[i];
        fnv_u64(f, (uint64_t)l->kind);
        const float v[] = {l->position.x,  l->position.y,        l->position.z,      l->direction.x,
                           l->direction.y, l->direction.z,       l->intensity.x,     l->intensity.y,
                           l->intensity.z, l->cos_falloff_start, l->cos_total_width, l->fov_deg};
        fnv_f32(f, v, sizeof v / sizeof v[0]);
        fnv_str(f, l->source);
    }
    for (int i = 0; i < s->material_count; i++) fnv_str(f, s->materials[i].description);
    for (int i = 0; i < s->image_count; i++)
        fnv_f32(f, s->images[i].rgb, 3 * (size_t)s->images[i].width * (size_t)s->images[i].height);
}

uint64_t pn_render_key(const pn_render_job *job, const pn_render_settings *settings, int integrator, int driver) {
    fnv f = {0xcbf29ce484222325ull};
    hash_scene(&f, job->scene);
    fnv_u64(&f, ((uint64_t)(uint32_t)integrator << 32) | (uint32_t)driver);
    const pn_camera *c = &job->camera;
    const int32_t win[6] = {c->full_width, c->full_height, c->x0, c->y0, c->x1, c->y1};
    fnv_bytes(&f, win, sizeof win);
    fnv_u64(&f, job->spp);
    fnv_bytes(&f, &job->threshold, sizeof job->threshold);
    fnv_u64(&f, job->seed);
    fnv_u64(&f, job->max_specular_depth);
    fnv_u64(&f, job->aovs);
    /* Every option's value in force, by name (the checkpoint's own file name and the bench's
     * tile-times file aside: neither changes a pixel). */
    int skip = pn_option_find("checkpoint"), skip_times = pn_option_find("tile-times");
    for (int i = 0; i < pn_option_count(); i++) {
        if (i == skip || i == skip_times) continue;
        char text[512] = "";
        pn_options_get(settings->options, i, NULL, text, sizeof text);
        fnv_str(&f, pn_option_get(i)->name);
        fnv_str(&f, text);
    }
    return f.h;
}

/* ---- the log ----------------------------------------------------------------------------- */

typedef struct ckpt_header {
    char magic[8];
    uint32_t version, header_size;
    uint64_t key;
    int32_t window[4];
    uint32_t tile_size, tile_count, estimate_size, reserved;
    uint64_t checksum; /* of the bytes before it */
} ckpt_header;

typedef struct ckpt_record {
    uint32_t magic, tile, payload, reserved;
    uint64_t checksum; /* of tile, payload size and the payload */
} ckpt_record;

struct pn_checkpoint {
    int fd;
    char *path;
};

static uint64_t record_checksum(uint32_t tile, uint32_t payload, const void *data) {
    fnv f = {0xcbf29ce484222325ull};
    fnv_u64(&f, ((uint64_t)tile << 32) | payload);
    fnv_bytes(&f, data, payload);
    return f.h;
}

static void fill_header(ckpt_header *h, uint64_t key, const pn_tile_grid *g) {
    memset(h, 0, sizeof *h);
    memcpy(h->magic, CKPT_MAGIC, 8);
    h->version = CKPT_VERSION;
    h->header_size = sizeof *h;
    h->key = key;
    h->window[0] = g->x0, h->window[1] = g->y0, h->window[2] = g->x1, h->window[3] = g->y1;
    h->tile_size = (uint32_t)g->size;
    h->tile_count = (uint32_t)g->count;
    h->estimate_size = sizeof(pn_pixel_estimate);
    h->checksum = fnv_of(h, offsetof(ckpt_header, checksum));
}

static pn_status write_all(int fd, const void *data, size_t n, const char *path, pn_err *err) {
    const char *p = data;
    while (n > 0) {
        ssize_t w = write(fd, p, n);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) return pn_err_set(err, PN_ERROR_IO, "%s: cannot write the checkpoint: %s", path, strerror(errno));
        p += w;
        n -= (size_t)w;
    }
    return PN_OK;
}

/* Syncs the folder holding path, so that a new file's name survives a crash. */
static void sync_folder(const char *path) {
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash)
        *(slash == dir ? slash + 1 : slash) = '\0';
    else
        snprintf(dir, sizeof dir, ".");
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd >= 0) {
        fsync(fd);
        close(fd);
    }
}

/* Reads the records of an existing checkpoint into window/done; returns the offset after the
 * last whole record. */
static pn_status read_records(int fd, const char *path, const pn_tile_grid *g, pn_pixel_estimate *window,
                              unsigned char *done, int *resumed, off_t *end, pn_err *err) {
    off_t at = sizeof(ckpt_header);
    size_t cap = 0;
    pn_pixel_estimate *buf = NULL;
    pn_status st = PN_OK;
    for (;;) {
        ckpt_record r;
        ssize_t n = pread(fd, &r, sizeof r, at);
        if (n == 0) break;
        if (n < 0) {
            st = pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(errno));
            break;
        }
        if ((size_t)n < sizeof r) break; /* torn: the record head was cut short */
        if (r.magic != TILE_MAGIC || r.tile >= (uint32_t)g->count ||
            r.payload != pn_tile_pixel_count(g, (int)r.tile) * sizeof(pn_pixel_estimate)) {
            st = pn_err_set(err, PN_ERROR_BAD_INPUT,
                            "%s: corrupt checkpoint: the record at byte %lld is not a tile of this render; delete the "
                            "file to start again",
                            path, (long long)at);
            break;
        }
        if (r.payload > cap) {
            pn_pixel_estimate *b = realloc(buf, r.payload);
            if (!b) {
                st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
                break;
            }
            buf = b;
            cap = r.payload;
        }
        n = pread(fd, buf, r.payload, at + (off_t)sizeof r);
        if (n < 0) {
            st = pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(errno));
            break;
        }
        if ((size_t)n < r.payload) break; /* torn: the payload was cut short */
        if (record_checksum(r.tile, r.payload, buf) != r.checksum) {
            st = pn_err_set(err, PN_ERROR_BAD_INPUT,
                            "%s: corrupt checkpoint: the checksum of tile %u (record at byte %lld) does not match; "
                            "delete the file to start again",
                            path, r.tile, (long long)at);
            break;
        }
        if (!done[r.tile]) {
            pn_tile_copy_in(g, (int)r.tile, buf, window);
            done[r.tile] = 1;
            (*resumed)++;
        }
        at += (off_t)(sizeof r + r.payload);
    }
    free(buf);
    *end = at;
    return st;
}

pn_status pn_checkpoint_open(const char *path, uint64_t key, const pn_tile_grid *g, pn_pixel_estimate *window,
                             unsigned char *done, int *resumed, pn_checkpoint **out, pn_err *err) {
    *out = NULL;
    *resumed = 0;
    ckpt_header want;
    fill_header(&want, key, g);
    int fd = open(path, O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    bool created = fd >= 0;
    if (!created && errno == EEXIST) fd = open(path, O_RDWR | O_CLOEXEC);
    if (fd < 0) return pn_err_set(err, PN_ERROR_IO, "%s: cannot open the checkpoint: %s", path, strerror(errno));
    /* An existing FIFO or device is neither read (it could block or never end) nor written. */
    struct stat info;
    memset(&info, 0, sizeof info);
    if (fstat(fd, &info) != 0 || !S_ISREG(info.st_mode)) {
        unsigned mode = (unsigned)info.st_mode;
        close(fd);
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: the checkpoint is %s; it must be a regular file", path,
                          pn_file_type_name(mode));
    }
    pn_status st = PN_OK;
    if (created) {
        st = write_all(fd, &want, sizeof want, path, err);
        if (st == PN_OK && fsync(fd) != 0)
            st = pn_err_set(err, PN_ERROR_IO, "%s: cannot sync the checkpoint: %s", path, strerror(errno));
        if (st == PN_OK) sync_folder(path);
        if (st != PN_OK) unlink(path);
    } else {
        ckpt_header have;
        ssize_t n = pread(fd, &have, sizeof have, 0);
        if (n != (ssize_t)sizeof have || memcmp(have.magic, CKPT_MAGIC, 8) != 0 ||
            have.checksum != fnv_of(&have, offsetof(ckpt_header, checksum)))
            st = pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a penumbra checkpoint (or its header is corrupt)", path);
        else if (have.version != want.version || have.header_size != want.header_size ||
                 have.estimate_size != want.estimate_size)
            st = pn_err_set(err, PN_ERROR_BAD_INPUT,
                            "%s: a checkpoint of another penumbra version (format %u, %u-byte pixels; this one "
                            "writes format %u, %u-byte pixels)",
                            path, have.version, have.estimate_size, want.version, want.estimate_size);
        else if (have.key != want.key)
            st = pn_err_set(err, PN_ERROR_BAD_INPUT,
                            "%s: the checkpoint was written for another render (scene contents, options or seed "
                            "differ: key %016llx, this render %016llx); delete it or give another --checkpoint",
                            path, (unsigned long long)have.key, (unsigned long long)want.key);
        else if (memcmp(have.window, want.window, sizeof want.window) != 0 || have.tile_size != want.tile_size ||
                 have.tile_count != want.tile_count)
            st = pn_err_set(err, PN_ERROR_BAD_INPUT,
                            "%s: the checkpoint's tiles (%u of %u pixels) are not this render's (%u of %u pixels)",
                            path, have.tile_count, have.tile_size, want.tile_count, want.tile_size);
        off_t end = 0;
        if (st == PN_OK) st = read_records(fd, path, g, window, done, resumed, &end, err);
        struct stat sb;
        if (st == PN_OK && fstat(fd, &sb) == 0 && sb.st_size > end) {
            /* A torn last record: drop it, so that new records follow whole ones. */
            if (ftruncate(fd, end) != 0 || fsync(fd) != 0)
                st = pn_err_set(err, PN_ERROR_IO, "%s: cannot drop a torn record: %s", path, strerror(errno));
        }
        if (st == PN_OK && lseek(fd, end, SEEK_SET) < 0)
            st = pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(errno));
    }
    pn_checkpoint *c = st == PN_OK ? calloc(1, sizeof *c) : NULL;
    if (st == PN_OK && (!c || !(c->path = strdup(path)))) {
        free(c);
        c = NULL;
        st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    }
    if (st != PN_OK) {
        close(fd);
        return st;
    }
    c->fd = fd;
    *out = c;
    return PN_OK;
}

pn_status pn_checkpoint_append(pn_checkpoint *c, int tile, const pn_pixel_estimate *packed, size_t count, pn_err *err) {
    size_t payload = count * sizeof *packed;
    size_t total = sizeof(ckpt_record) + payload;
    char *buf = malloc(total);
    if (!buf) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", c->path);
    ckpt_record r = {TILE_MAGIC, (uint32_t)tile, (uint32_t)payload, 0, 0};
    r.checksum = record_checksum(r.tile, r.payload, packed);
    memcpy(buf, &r, sizeof r);
    memcpy(buf + sizeof r, packed, payload);
    /* One write, then a data sync: a kill leaves whole records and at most one torn tail. */
    pn_status st = write_all(c->fd, buf, total, c->path, err);
    free(buf);
    if (st == PN_OK && fdatasync(c->fd) != 0)
        st = pn_err_set(err, PN_ERROR_IO, "%s: cannot sync the checkpoint: %s", c->path, strerror(errno));
    return st;
}

void pn_checkpoint_close(pn_checkpoint *c) {
    if (!c) return;
    close(c->fd);
    free(c->path);
    free(c);
}
