/* test_robust.c — hostile files and outputs that are never lost or misplaced (issue 19).
 *
 * Each case reproduces one finding of the issue as a user or a hostile file would: a device or a
 * FIFO named as a scene, Include, PLY mesh or texture (must fail at once, neither growing memory
 * nor blocking), an input larger than the limit, outputs whose target is not a regular file (must
 * be refused, never replaced), a failing --png or --stats (must leave no -o image), a signal while
 * the outputs are written (must leave no temporary), and the worker-thread limit and failure
 * messages. The CLI cases run the built binary in a private folder with a time limit per run.
 */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE /* pthread_setattr_default_np */
#endif

#define PN_SCENE_FILES_PREFIX "pn_test_robust"
#include "harness.h"
#include "scene_files.h"

#include "core/text.h"
#include "io/image.h"
#include "scene/photometry.h"

#include <penumbra/penumbra.h>

#include <dirent.h>
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#ifndef PN_CLI_PATH
#error "PN_CLI_PATH must name the penumbra binary (see tests/robust.cmake)"
#endif

/* ---------------------------------------------------------------------------------------- */
/* Running the program in the temporary folder */

typedef struct cli_run {
    int status; /* exit status, 128 + signal, or -1 when it timed out */
    char err[4096];
} cli_run;

/* Starts `penumbra args...` in the temporary folder with stderr going to cli.stderr. */
static pid_t cli_start(const char *const *args) {
    char *argv[32];
    int argc = 0;
    argv[argc++] = (char *)PN_CLI_PATH;
    for (int i = 0; args[i] && argc < 31; i++) argv[argc++] = (char *)args[i];
    argv[argc] = NULL;
    const char *dir = temp_dir();
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    if (pid == 0) {
        int err_fd = open(tpath("cli.stderr"), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        int null_fd = open("/dev/null", O_RDWR);
        if (err_fd < 0 || null_fd < 0 || chdir(dir) != 0) _exit(126);
        dup2(null_fd, STDIN_FILENO);
        dup2(null_fd, STDOUT_FILENO);
        dup2(err_fd, STDERR_FILENO);
        execv(PN_CLI_PATH, argv);
        _exit(127);
    }
    return pid;
}

static double now_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Waits for the child at most `limit` seconds (then kills it: status -1) and reads its stderr. */
static cli_run cli_finish(pid_t pid, double limit) {
    cli_run r = {-1, ""};
    int wstatus = 0;
    double start = now_seconds();
    struct timespec pause = {0, 2 * 1000 * 1000};
    while (waitpid(pid, &wstatus, WNOHANG) != pid) {
        if (now_seconds() - start > limit) {
            kill(pid, SIGKILL);
            waitpid(pid, &wstatus, 0);
            wstatus = -1;
            break;
        }
        nanosleep(&pause, NULL);
    }
    if (wstatus != -1) r.status = WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : 128 + WTERMSIG(wstatus);
    FILE *f = fopen(tpath("cli.stderr"), "rb");
    if (f) {
        size_t n = fread(r.err, 1, sizeof r.err - 1, f);
        r.err[n] = '\0';
        fclose(f);
    }
    return r;
}

#define CLI_EXPECT(result, expected, ...)                                                                              \
    do {                                                                                                               \
        const char *const pn_args_[] = {__VA_ARGS__, NULL};                                                            \
        result = cli_finish(cli_start(pn_args_), 10.0);                                                                \
        CHECK_MSG(result.status == (expected), "penumbra %s %s: exit %d, expected %d; stderr: %s", pn_args_[0],        \
                  pn_args_[1], result.status, (expected), result.err);                                                 \
    } while (0)

static int exists(const char *rel) {
    struct stat st;
    return lstat(tpath(rel), &st) == 0;
}

/* Number of files in the folder whose name contains ".tmp-" or ".pn-tmp-" (the writer's
 * temporaries). */
static int temporaries_left(void) {
    DIR *dir = opendir(temp_dir());
    int n = 0;
    struct dirent *e;
    while (dir && (e = readdir(dir)) != NULL) n += strstr(e->d_name, ".tmp-") != NULL;
    if (dir) closedir(dir);
    return n;
}

static const char tiny_scene[] = "LookAt 0 0 -3  0 0 0  0 1 0\n"
                                 "Camera \"perspective\" \"float fov\" [ 45 ]\n"
                                 "Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\n"
                                 "WorldBegin\n"
                                 "LightSource \"point\" \"point3 from\" [ 0.3 0.2 -1 ] \"rgb I\" [ 1 1 1 ]\n"
                                 "Material \"diffuse\"\n"
                                 "Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ]\n"
                                 "    \"point3 P\" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ]\n";

static void make_fifo(const char *rel) {
    unlink(tpath(rel));
    CHECK(mkfifo(tpath(rel), 0644) == 0);
}

/* ---------------------------------------------------------------------------------------- */
/* Finding 3: inputs must be regular files within a size limit */

static void test_device_as_scene_or_include(void) {
    cli_run r;
    double t0 = now_seconds();
    CLI_EXPECT(r, 3, "info", "/dev/zero");
    CHECK_STR_CONTAINS(r.err, "character device");
    write_file("inc_zero.pbrt", "WorldBegin\nInclude \"/dev/zero\"\n");
    CLI_EXPECT(r, 3, "info", "inc_zero.pbrt");
    CHECK_STR_CONTAINS(r.err, "inc_zero.pbrt:2:9:");
    CHECK_STR_CONTAINS(r.err, "character device");
    /* Without the check each run grows memory until killed; with it both fail at once. */
    CHECK_MSG(now_seconds() - t0 < 8.0, "took %.1f s", now_seconds() - t0);
}

static void test_fifo_inputs_do_not_block(void) {
    cli_run r;
    make_fifo("fifo.pbrt");
    write_file("inc_fifo.pbrt", "WorldBegin\nInclude \"fifo.pbrt\"\n");
    CLI_EXPECT(r, 3, "info", "inc_fifo.pbrt");
    CHECK_STR_CONTAINS(r.err, "a FIFO");

    make_fifo("fifo.ply");
    write_file("ply_fifo.pbrt", "WorldBegin\nShape \"plymesh\" \"string filename\" \"fifo.ply\"\n");
    CLI_EXPECT(r, 3, "info", "ply_fifo.pbrt");
    CHECK_STR_CONTAINS(r.err, "fifo.ply");
    CHECK_STR_CONTAINS(r.err, "a FIFO");

    make_fifo("fifo.png");
    write_file("tex_fifo.pbrt", "WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"fifo.png\"\n"
                                "Material \"diffuse\" \"texture reflectance\" \"t\"\n"
                                "Shape \"sphere\"\n");
    CLI_EXPECT(r, 3, "info", "tex_fifo.pbrt");
    CHECK_STR_CONTAINS(r.err, "fifo.png");
    CHECK_STR_CONTAINS(r.err, "a FIFO");
}

/* The readers added since: photometric files (goniometric lights), spectrum files and the
 * checkpoint of the tiles driver take only regular files too (before, a FIFO blocked the first
 * two; the checkpoint was refused only as "not a penumbra checkpoint"). */
static void test_fifo_photometry_spectrum_checkpoint(void) {
    cli_run r;
    make_fifo("fifo.ies");
    write_file("ies_fifo.pbrt", "WorldBegin\nLightSource \"goniometric\" \"string filename\" \"fifo.ies\"\n");
    CLI_EXPECT(r, 3, "info", "ies_fifo.pbrt");
    CHECK_STR_CONTAINS(r.err, "fifo.ies: cannot open the photometric file: is a FIFO");
    CHECK_STR_CONTAINS(r.err, "ies_fifo.pbrt:2:");

    make_fifo("fifo.spd");
    write_file("spd_fifo.pbrt", "WorldBegin\nMaterial \"diffuse\" \"spectrum reflectance\" \"fifo.spd\"\n"
                                "Shape \"sphere\"\n");
    CLI_EXPECT(r, 3, "info", "spd_fifo.pbrt");
    CHECK_STR_CONTAINS(r.err, "spd_fifo.pbrt:2:");
    CHECK_STR_CONTAINS(r.err, "fifo.spd\": is a FIFO");

    write_file("tiny.pbrt", tiny_scene);
    make_fifo("fifo.ckpt");
    CLI_EXPECT(r, 3, "render", "tiny.pbrt", "--driver", "tiles", "--checkpoint", "fifo.ckpt", "-o", "ck.exr",
               "--quiet");
    CHECK_STR_CONTAINS(r.err, "fifo.ckpt: the checkpoint is a FIFO; it must be a regular file");
    struct stat st;
    CHECK(lstat(tpath("fifo.ckpt"), &st) == 0 && S_ISFIFO(st.st_mode));
    CHECK(!exists("ck.exr"));
}

static void test_input_larger_than_limit(void) {
    /* A sparse file one byte over the limit: refused from its size, never read. */
    int fd = open(tpath("huge.pbrt"), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    CHECK(fd >= 0);
    if (fd < 0) return;
    int ok = ftruncate(fd, (off_t)((uint64_t)1 << 33) + 1) == 0;
    close(fd);
    if (!ok) {
        pn_test_skip("the file system cannot hold a sparse 8 GiB file");
        return;
    }
    cli_run r;
    CLI_EXPECT(r, 3, "info", "huge.pbrt");
    CHECK_STR_CONTAINS(r.err, "larger than the limit");
    unlink(tpath("huge.pbrt"));
}

/* ---------------------------------------------------------------------------------------- */
/* Findings 5 and 7: outputs replace only regular files, and a failed output leaves none */

static void test_outputs_refuse_non_regular_targets(void) {
    cli_run r;
    write_file("tiny.pbrt", tiny_scene);
    /* A FIFO stands for a device such as /dev/full: renaming over it would destroy it. */
    make_fifo("stats.json");
    unlink(tpath("a.exr"));
    CLI_EXPECT(r, 4, "render", "tiny.pbrt", "--spp", "1", "-o", "a.exr", "--stats", "stats.json", "--quiet");
    CHECK_STR_CONTAINS(r.err, "stats.json: is a FIFO");
    struct stat st;
    CHECK(lstat(tpath("stats.json"), &st) == 0 && S_ISFIFO(st.st_mode));
    CHECK_MSG(!exists("a.exr"), "a failed --stats left the -o image");

    /* A symbolic link is not replaced, and its target not written. */
    write_file("target.json", "keep");
    unlink(tpath("link.json"));
    CHECK(symlink("target.json", tpath("link.json")) == 0);
    CLI_EXPECT(r, 4, "render", "tiny.pbrt", "--spp", "1", "-o", "a.exr", "--stats", "link.json", "--quiet");
    CHECK_STR_CONTAINS(r.err, "link.json: is a symbolic link");
    CHECK(lstat(tpath("link.json"), &st) == 0 && S_ISLNK(st.st_mode));
    CHECK_MSG(!exists("a.exr"), "a failed --stats left the -o image");
    CHECK(temporaries_left() == 0);

    /* The image itself likewise. */
    make_fifo("fifo.exr");
    CLI_EXPECT(r, 4, "render", "tiny.pbrt", "--spp", "1", "-o", "fifo.exr", "--quiet");
    CHECK(lstat(tpath("fifo.exr"), &st) == 0 && S_ISFIFO(st.st_mode));
}

static void test_failed_png_leaves_no_image(void) {
    cli_run r;
    write_file("tiny.pbrt", tiny_scene);
    unlink(tpath("b.exr"));
    mkdir(tpath("b.png"), 0755);
    CLI_EXPECT(r, 4, "render", "tiny.pbrt", "--spp", "1", "-o", "b.exr", "--png", "b.png", "--stats", "b.json",
               "--quiet");
    CHECK_STR_CONTAINS(r.err, "b.png");
    CHECK_MSG(!exists("b.exr"), "a failed --png left the -o image");
    CHECK_MSG(!exists("b.json"), "a failed --png left the statistics");
    CHECK(temporaries_left() == 0);
    rmdir(tpath("b.png"));
    /* The same run with a writable PNG writes all three. */
    CLI_EXPECT(r, 0, "render", "tiny.pbrt", "--spp", "1", "-o", "b.exr", "--png", "b.png", "--stats", "b.json",
               "--quiet");
    CHECK(exists("b.exr") && exists("b.png") && exists("b.json"));
}

/* ---------------------------------------------------------------------------------------- */
/* Finding 6: a signal while the outputs are written leaves no temporary */

static void test_signal_while_writing_leaves_no_temporary(void) {
    /* A large image with every AOV takes long enough to write (zip-compressed EXR layers) that
     * the temporary is seen, and SIGTERM sent, while it is being written. */
    write_file("big.pbrt", "LookAt 0 0 -3  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 45 ]\n"
                           "Film \"rgb\" \"integer xresolution\" [ 1024 ] \"integer yresolution\" [ 1024 ]\n"
                           "WorldBegin\n");
    int caught = 0;
    for (int attempt = 0; attempt < 5 && !caught; attempt++) {
        unlink(tpath("big.exr"));
        const char *const args[] = {"render", "big.pbrt", "--spp",   "1",       "--aov",
                                    "all",    "-o",       "big.exr", "--quiet", NULL};
        pid_t pid = cli_start(args);
        double start = now_seconds();
        struct timespec pause = {0, 200 * 1000};
        while (now_seconds() - start < 20.0) {
            if (temporaries_left() > 0) {
                kill(pid, SIGTERM);
                caught = 1;
                break;
            }
            if (waitpid(pid, NULL, WNOHANG) == pid) {
                pid = -1;
                break;
            }
            nanosleep(&pause, NULL);
        }
        if (pid > 0) {
            cli_run r = cli_finish(pid, 20.0);
            if (caught) CHECK_MSG(r.status == 128 + SIGTERM || r.status == 0, "exit %d: %s", r.status, r.err);
        }
    }
    if (!caught) {
        pn_test_skip("the writing was too quick to be interrupted");
        return;
    }
    CHECK_MSG(temporaries_left() == 0, "%d temporaries left after SIGTERM", temporaries_left());
}

/* ---------------------------------------------------------------------------------------- */
/* Finding 8: the thread limit is stated, and a thread-creation failure says so */

static void test_thread_limit_stated(void) {
    cli_run r;
    write_file("tiny.pbrt", tiny_scene);
    char limit[32];
    snprintf(limit, sizeof limit, "%d", PN_MAX_THREADS);
    CLI_EXPECT(r, 2, "render", "tiny.pbrt", "--threads", "100000", "-o", "t.exr");
    CHECK_STR_CONTAINS(r.err, limit);
    char over[32];
    snprintf(over, sizeof over, "%d", PN_MAX_THREADS + 1);
    CLI_EXPECT(r, 2, "render", "tiny.pbrt", "--threads", over, "-o", "t.exr");
    CHECK(!exists("t.exr"));

    /* The library refuses more than the limit rather than capping it silently. */
    pn_scene scene = NULL;
    CHECK(pn_scene_load(test_context(), tpath("tiny.pbrt"), &scene) == PN_OK);
    pn_render_settings s = {.threads = PN_MAX_THREADS + 1, .spp = 1};
    pn_image image = NULL;
    CHECK(pn_render(test_context(), scene, &s, &image, NULL) == PN_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(pn_context_error_message(test_context()), limit);
    pn_context_clear_error(test_context());
    pn_image_free(image);
    pn_scene_free(scene);
}

static void test_thread_creation_failure_message(void) {
    pn_scene scene = NULL;
    write_file("tiny.pbrt", tiny_scene);
    CHECK(pn_scene_load(test_context(), tpath("tiny.pbrt"), &scene) == PN_OK);
    /* Threads whose stacks cannot be mapped: pthread_create fails (EAGAIN) as under ulimit -u. */
    pthread_attr_t attr, saved;
    CHECK(pthread_getattr_default_np(&saved) == 0);
    pthread_attr_init(&attr);
    CHECK(pthread_attr_setstacksize(&attr, (size_t)1 << 46) == 0);
    CHECK(pthread_setattr_default_np(&attr) == 0);
    pn_render_settings s = {.threads = 4, .spp = 1};
    pn_image image = NULL;
    pn_status st = pn_render(test_context(), scene, &s, &image, NULL);
    pthread_setattr_default_np(&saved);
    pthread_attr_destroy(&attr);
    pthread_attr_destroy(&saved);
    CHECK(st != PN_OK);
    const char *message = pn_context_error_message(test_context());
    CHECK_STR_CONTAINS(message, "cannot start the worker threads");
    CHECK_MSG(strstr(message, "out of memory") == NULL, "message: %s", message);
    pn_context_clear_error(test_context());
    pn_image_free(image);
    pn_scene_free(scene);
}

/* ---------------------------------------------------------------------------------------- */
/* Finding 2: one pixel limit for every format, checked against the header and the file size */

static void write_bytes(const char *rel, const void *data, size_t size) {
    FILE *f = fopen(tpath(rel), "wb");
    CHECK(f != NULL);
    if (!f) return;
    CHECK(fwrite(data, 1, size, f) == size);
    fclose(f);
}

static void test_decompression_bomb_tga(void) {
    /* An 18-byte uncompressed 24-bit TGA header claiming 57112 x 1293 pixels and no data. */
    unsigned char tga[18] = {0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x18, 0xdf, 0x0d, 0x05, 24, 0};
    write_bytes("bomb.tga", tga, sizeof tga);
    cli_run r;
    double t0 = now_seconds();
    CLI_EXPECT(r, 3, "diff", "bomb.tga", "bomb.tga");
    CHECK_STR_CONTAINS(r.err, "57112x1293 pixels cannot be stored in 18 bytes");
    CHECK_MSG(now_seconds() - t0 < 2.0, "took %.2f s", now_seconds() - t0);
}

/* Finding 1: the 9-byte JPEG whose Huffman counts sum past 256 (stb wrote past its table) is
 * refused by libjpeg-turbo; under UBSan, fuzz_replay_jpeg replays it from the corpus. */
static void test_forged_huffman_table_jpeg(void) {
    static const unsigned char jpeg[9] = {0xff, 0xd8, 0xff, 0xc4, 0x00, 0x13, 0x00, 0xff, 0xff};
    write_bytes("huffman.jpg", jpeg, sizeof jpeg);
    pn_image out = NULL;
    CHECK(pn_image_read(test_context(), tpath("huffman.jpg"), &out) == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(pn_context_error_message(test_context()), "not a valid JPEG file: Bogus Huffman table");
    pn_context_clear_error(test_context());
    pn_image_free(out);
}

/* Overwrites n bytes at `offset` past the first `key` (key_size bytes, NULs included) in the
 * first 4 KB of file `rel`. Returns 1 when the key was found. */
static int patch_file(const char *rel, const char *key, size_t key_size, size_t offset, const void *bytes, size_t n) {
    FILE *f = fopen(tpath(rel), "r+b");
    if (!f) return 0;
    unsigned char header[4096];
    size_t got = fread(header, 1, sizeof header, f);
    int found = 0;
    for (size_t i = 0; i + key_size + offset + n <= got && !found; i++)
        if (memcmp(header + i, key, key_size) == 0) {
            memcpy(header + i + key_size + offset, bytes, n);
            found = 1;
        }
    fseek(f, 0, SEEK_SET);
    found = fwrite(header, 1, got, f) == got && found;
    fclose(f);
    return found;
}

/* Writes a size x size EXR to `rel` and patches it as patch_file does. */
static int write_patched_exr(const char *rel, int size, const char *key, size_t key_size, size_t offset,
                             const void *bytes, size_t n) {
    pn_image img = pn_image_create(size, size);
    CHECK(pn_image_write(test_context(), img, tpath(rel), 0.0f) == PN_OK);
    pn_image_free(img);
    return patch_file(rel, key, key_size, offset, bytes, n);
}

/* An EXR whose data window is patched to 16384 x 16384 while the file stays small. */
static void test_exr_data_window_against_file_size(void) {
    static const char key[] = "dataWindow\0box2i";
    int32_t box[4] = {0, 0, 16383, 16383}; /* after the 4-byte size; little-endian as EXR is */
    CHECK(write_patched_exr("small.exr", 8, key, sizeof key, 4, box, sizeof box));
    pn_image out = NULL;
    CHECK(pn_image_read(test_context(), tpath("small.exr"), &out) == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(pn_context_error_message(test_context()), "cannot be stored in");
    pn_context_clear_error(test_context());
    pn_image_free(out);
}

/* The layer reader of `penumbra merge` takes the pixel limit: a hostile header whose data and
 * display windows claim 16384 x 16384 pixels in a few hundred bytes is refused before any pixel
 * is allocated, and the context's limit is applied to pixels and to samples (pixels x channels). */
static void test_exr_layers_pixel_limit(void) {
    static const char data_key[] = "dataWindow\0box2i", display_key[] = "displayWindow\0box2i";
    int32_t box[4] = {0, 0, 16383, 16383};
    CHECK(write_patched_exr("part.exr", 8, data_key, sizeof data_key, 4, box, sizeof box));
    CHECK(patch_file("part.exr", display_key, sizeof display_key, 4, box, sizeof box));
    cli_run r;
    double t0 = now_seconds();
    CLI_EXPECT(r, 3, "merge", "part.exr", "-o", "full.exr");
    CHECK_STR_CONTAINS(r.err, "part.exr: not a valid EXR file: 16384x16384 pixels in ");
    CHECK_STR_CONTAINS(r.err, "chunks cannot be stored in");
    CHECK_MSG(now_seconds() - t0 < 2.0, "took %.2f s", now_seconds() - t0);
    CHECK(!exists("full.exr"));

    /* 64 x 64 pixels, the beauty and a three-channel layer: 4096 pixels, 6 x 4096 samples. */
    pn_image img = pn_image_create(64, 64);
    CHECK(img && pn_image_add_layer(img, "normal", 3) != NULL);
    CHECK(pn_image_write(test_context(), img, tpath("layers.exr"), 0.0f) == PN_OK);
    pn_image_free(img);
    pn_context ctx = pn_context_new();
    pn_image out = NULL;
    pn_context_set_image_pixel_limit(ctx, 4095);
    CHECK(pn_image_read_layers(ctx, tpath("layers.exr"), &out) == PN_ERROR_BAD_INPUT && !out);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "EXR image of 64x64 pixels is larger than the image pixel limit "
                                                      "of 4095 pixels");
    pn_context_clear_error(ctx);
    pn_context_set_image_pixel_limit(ctx, 8191);
    CHECK(pn_image_read_layers(ctx, tpath("layers.exr"), &out) == PN_ERROR_BAD_INPUT && !out);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "EXR image of 64x64 pixels with 6 channels is larger than the "
                                                      "image pixel limit of 8191 pixels with 3 channels");
    pn_context_clear_error(ctx);
    pn_context_set_image_pixel_limit(ctx, 8192);
    CHECK(pn_image_read_layers(ctx, tpath("layers.exr"), &out) == PN_OK && out && out->layer_count == 2);
    pn_image_free(out);
    pn_context_free(ctx);
    /* `penumbra merge --max-image-pixels` reads its parts under that limit. */
    CLI_EXPECT(r, 3, "merge", "layers.exr", "-o", "merged.exr", "--max-image-pixels", "4095");
    CHECK_STR_CONTAINS(r.err, "EXR image of 64x64 pixels is larger than the image pixel limit of 4095 pixels");
    CHECK(!exists("merged.exr"));
    CLI_EXPECT(r, 2, "merge", "layers.exr", "-o", "merged.exr", "--max-image-pixels", "0");
    CLI_EXPECT(r, 0, "merge", "layers.exr", "-o", "merged.exr", "--max-image-pixels", "8192");
    CHECK(exists("merged.exr"));
}

/* A NUL byte in a points file of `penumbra illuminance` is refused where it is (before, the line
 * ended there and what followed it on the line was silently dropped). */
static void test_points_file_nul_byte(void) {
    static const char points[] = "0 0 0 0 0 1\n0 0 0.5 0 0 1\0 garbage\n";
    write_bytes("nul.pts", points, sizeof points - 1);
    write_file("empty.pbrt", "WorldBegin\n");
    cli_run r;
    CLI_EXPECT(r, 3, "illuminance", "empty.pbrt", "--points", "nul.pts", "-o", "nul.csv", "--quiet");
    CHECK_STR_CONTAINS(r.err, "nul.pts:2:14: a NUL byte: not a text file");
    CHECK(!exists("nul.csv"));
    write_bytes("ok.pts", points, 25); /* the same two points without the NUL byte and after */
    CLI_EXPECT(r, 0, "illuminance", "empty.pbrt", "--points", "ok.pts", "-o", "ok.csv", "--quiet");
    CHECK(exists("ok.csv"));
}

/* Counts in a photometric header are checked against the bytes left in the file before the
 * table is allocated: a 200-byte IES file claiming 3000 x 3333 angles (80 MB of doubles) and a
 * TILT=INCLUDE block claiming 100000 tilt angles are refused with file:line. */
static void test_photometry_counts_against_file_size(void) {
    static const char table[] = "IESNA:LM-63-2002\nTILT=NONE\n1 1000 1 3000 3333 1 2 0 0 0\n1 1 100\n0 1 2\n";
    write_file("forged.ies", table);
    pn_photometry *p = NULL;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_photometry_read(tpath("forged.ies"), "forged.ies", &p, &err) == PN_ERROR_BAD_INPUT && !p);
    CHECK_STR_CONTAINS(err.message, "forged.ies:4:5: 9999000 intensities cannot be stored in the ");
    static const char tilt[] = "IESNA:LM-63-2002\nTILT=INCLUDE\n1\n100000\n0 90 180\n";
    write_file("tilt.ies", tilt);
    pn_err_init(&err);
    CHECK(pn_photometry_read(tpath("tilt.ies"), "tilt.ies", &p, &err) == PN_ERROR_BAD_INPUT && !p);
    CHECK_STR_CONTAINS(err.message, "tilt.ies:4:1: 200000 tilt angles and factors cannot be stored in the ");
    /* The same header with its real counts is read. */
    static const char real[] = "IESNA:LM-63-2002\nTILT=NONE\n1 1000 1 3 1 1 2 0 0 0\n1 1 100\n0 45 90\n0\n"
                               "100 80 0\n";
    write_file("real.ies", real);
    pn_err_init(&err);
    CHECK_MSG(pn_photometry_read(tpath("real.ies"), "real.ies", &p, &err) == PN_OK && p, "%s", err.message);
    pn_photometry_free(p);
}

static void test_pixel_limit_option_and_texture_cost(void) {
    pn_image img = pn_image_create(512, 512);
    CHECK(pn_image_write(test_context(), img, tpath("tex.pfm"), 0.0f) == PN_OK);
    CHECK(pn_image_write(test_context(), img, tpath("tex.exr"), 0.0f) == PN_OK);
    pn_image_free(img);
    write_file("tex.pbrt", "WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"tex.pfm\"\n"
                           "Texture \"u\" \"spectrum\" \"imagemap\" \"string filename\" \"tex.exr\"\n"
                           "Material \"diffuse\" \"texture reflectance\" \"t\"\n"
                           "Shape \"sphere\"\n");
    cli_run r;
    /* Two 512 x 512 RGB float images (2 x 3 MiB) and their two pyramids, levels 512^2 ... 1^2:
     * 349525 pixels each. */
    CLI_EXPECT(r, 0, "info", "tex.pbrt");
    pn_scene scene = NULL;
    CHECK(pn_scene_load(test_context(), tpath("tex.pbrt"), &scene) == PN_OK);
    pn_scene_info info;
    CHECK(pn_scene_get_info(scene, &info) == PN_OK);
    CHECK(info.texture_images == 2);
    CHECK_MSG(info.texture_bytes == 2u * (512u * 512u + 349525u) * 3u * sizeof(float), "%llu bytes",
              (unsigned long long)info.texture_bytes);
    pn_scene_free(scene);

    CLI_EXPECT(r, 3, "info", "tex.pbrt", "--max-image-pixels", "1000");
    CHECK_STR_CONTAINS(r.err, "tex.pfm: PFM image of 512x512 pixels is larger than the image pixel limit of 1000");
    CLI_EXPECT(r, 0, "info", "tex.pbrt", "--max-image-pixels", "262144");
    CLI_EXPECT(r, 2, "info", "tex.pbrt", "--max-image-pixels", "0");
    CLI_EXPECT(r, 3, "diff", "tex.exr", "tex.exr", "--max-image-pixels", "1000");
    CHECK_STR_CONTAINS(r.err, "tex.exr: EXR image of 512x512 pixels is larger than the image pixel limit of 1000");
}

/* ---------------------------------------------------------------------------------------- */
/* Finding 4: every message built from file content is one line, control bytes escaped */

/* Whether s is one line of printable text (UTF-8 above 0x7f allowed; no C0 control, no DEL). */
static int printable_line(const char *s) {
    for (const unsigned char *p = (const unsigned char *)s; *p; p++)
        if (*p < 0x20 || *p == 0x7f) return 0;
    return 1;
}

static void test_text_escape(void) {
    char out[64];
    CHECK(strcmp(pn_text_escape(out, sizeof out, "a\nb\x1b[31m\\n"), "a\\x0ab\\x1b[31m\\n") == 0);
    /* Well-formed UTF-8 stays; a C1 control (U+009B, CSI), a lone continuation byte and an
     * overlong form are escaped. */
    CHECK(strcmp(pn_text_escape(out, sizeof out, "caf\xc3\xa9 \xc2\x9b \x80 \xc0\xaf"),
                 "caf\xc3\xa9 \\xc2\\x9b \\x80 \\xc0\\xaf") == 0);
    /* Escaping twice changes nothing; truncation never splits an escape. */
    char again[64];
    CHECK(strcmp(pn_text_escape(again, sizeof again, out), out) == 0);
    CHECK(strcmp(pn_text_escape(out, 6, "ab\x01"), "ab") == 0);
    CHECK(strcmp(pn_text_escape(out, 7, "ab\x01"), "ab\\x01") == 0);
}

static void test_messages_are_one_printable_line(void) {
    /* A string with an escaped newline and a raw ESC sequence, echoed by the parser. */
    write_file("esc.pbrt", "WorldBegin\nShape \"sph\\nere\x1b[31m\"\n");
    pn_scene scene = NULL;
    CHECK(pn_scene_load(test_context(), tpath("esc.pbrt"), &scene) == PN_OK);
    CHECK(pn_scene_warning_count(scene) == 1);
    const char *warning = pn_scene_warning(scene, 0);
    CHECK_STR_CONTAINS(warning, "sph\\x0aere\\x1b[31m");
    CHECK(printable_line(warning));
    pn_scene_free(scene);

    /* 4 KB of bytes of every value as a scene: the error is one printable line. */
    char junk[4096];
    uint32_t x = 12345;
    for (size_t i = 0; i < sizeof junk; i++) {
        x = x * 1664525u + 1013904223u;
        junk[i] = (char)(x >> 24);
    }
    junk[0] = '"'; /* a string token that runs over control bytes */
    write_bytes("junk.pbrt", junk, sizeof junk);
    CHECK(pn_scene_load(test_context(), tpath("junk.pbrt"), &scene) != PN_OK);
    CHECK_MSG(printable_line(pn_context_error_message(test_context())), "%s", pn_context_error_message(test_context()));
    pn_context_clear_error(test_context());
    pn_scene_free(scene);

    /* An EXR attribute type name with an ESC in it ("chl\x1bst"), quoted by OpenEXR's message. */
    static const char key[] = "channels\0chl";
    CHECK(write_patched_exr("attr.exr", 4, key, sizeof key - 1, 0, "\x1b", 1));
    pn_image out = NULL;
    CHECK(pn_image_read(test_context(), tpath("attr.exr"), &out) != PN_OK);
    const char *message = pn_context_error_message(test_context());
    CHECK_MSG(printable_line(message), "%s", message);
    CHECK_STR_CONTAINS(message, "\\x1b");
    pn_context_clear_error(test_context());
    pn_image_free(out);
}

/* Removes the files of the temporary folder (no sub-folders are made) and the folder. */
static void remove_temp_dir(void) {
    DIR *dir = opendir(temp_dir());
    struct dirent *e;
    while (dir && (e = readdir(dir)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        const char *p = tpath(e->d_name);
        if (rmdir(p) != 0) unlink(p);
    }
    if (dir) closedir(dir);
    rmdir(temp_dir());
}

static void test_cleanup(void) {
    remove_temp_dir();
    CHECK(!exists(""));
}

PN_TESTS(TEST(test_device_as_scene_or_include), TEST(test_fifo_inputs_do_not_block), TEST(test_input_larger_than_limit),
         TEST(test_outputs_refuse_non_regular_targets), TEST(test_failed_png_leaves_no_image),
         TEST(test_signal_while_writing_leaves_no_temporary), TEST(test_thread_limit_stated),
         TEST(test_thread_creation_failure_message), TEST(test_decompression_bomb_tga),
         TEST(test_forged_huffman_table_jpeg), TEST(test_exr_data_window_against_file_size),
         TEST(test_exr_layers_pixel_limit), TEST(test_photometry_counts_against_file_size),
         TEST(test_fifo_photometry_spectrum_checkpoint), TEST(test_points_file_nul_byte),
         TEST(test_pixel_limit_option_and_texture_cost), TEST(test_text_escape),
         TEST(test_messages_are_one_printable_line), TEST(test_cleanup))
