/* test_cli.c — end-to-end tests of the `penumbra` program: exit codes, messages, output files.
 *
 * Each test writes small .pbrt files into a private temporary folder, runs the built binary there
 * (fork + execv, stdout and stderr captured in files, a time limit per run) and checks the exit
 * status, what was printed and which files exist afterwards. Scene errors must name the exact
 * file:line:column, and no failed run may leave an output image behind.
 */
#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 200809L
#endif
#ifndef _DEFAULT_SOURCE
#define _DEFAULT_SOURCE
#endif

#include "harness.h"

#include <penumbra/penumbra.h>

#include <errno.h>
#include <fcntl.h>
#include <dirent.h>
#include <signal.h>
#include <stdint.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#ifndef PN_CLI_PATH
#error "PN_CLI_PATH must name the penumbra binary (see tests/cli.cmake)"
#endif

/* ---------------------------------------------------------------------------------------- */
/* Temporary folder and files */

static char work_dir[256];

/* Removes a folder and everything in it (no symbolic links are followed). */
static void remove_tree(const char *path) {
    DIR *dir = opendir(path);
    struct dirent *entry;
    if (dir == NULL) return;
    while ((entry = readdir(dir)) != NULL) {
        char child[1024];
        struct stat st;
        if (strcmp(entry->d_name, ".") == 0 || strcmp(entry->d_name, "..") == 0) continue;
        snprintf(child, sizeof child, "%s/%s", path, entry->d_name);
        if (lstat(child, &st) == 0 && S_ISDIR(st.st_mode))
            remove_tree(child);
        else
            remove(child);
    }
    closedir(dir);
    rmdir(path);
}

static void remove_work_dir(void) {
    if (work_dir[0] && getenv("PN_KEEP_TEST_DIR") == NULL) remove_tree(work_dir);
}

/* Creates the work folder on first use; all paths below are relative to it. */
static const char *work(void) {
    if (work_dir[0] == '\0') {
        const char *tmp = getenv("TMPDIR");
        snprintf(work_dir, sizeof work_dir, "%s/penumbra-cli-XXXXXX", tmp && tmp[0] ? tmp : "/tmp");
        if (mkdtemp(work_dir) == NULL) {
            fprintf(stderr, "mkdtemp failed: %s\n", strerror(errno));
            exit(1);
        }
        atexit(remove_work_dir);
    }
    return work_dir;
}

static void work_path(const char *name, char *out, size_t size) {
    snprintf(out, size, "%s/%s", work(), name);
}

static void write_file(const char *name, const char *text) {
    char path[512];
    work_path(name, path, sizeof path);
    FILE *f = fopen(path, "w");
    if (f == NULL) {
        fprintf(stderr, "cannot write %s: %s\n", path, strerror(errno));
        exit(1);
    }
    fputs(text, f);
    fclose(f);
}

/* Whole file as a NUL-terminated string (caller frees), or NULL if it cannot be read. */
static char *read_file(const char *name, size_t *size_out) {
    char path[512];
    work_path(name, path, sizeof path);
    FILE *f = fopen(path, "rb");
    if (f == NULL) return NULL;
    size_t cap = 4096, size = 0;
    char *data = malloc(cap);
    size_t n;
    while (data && (n = fread(data + size, 1, cap - size - 1, f)) > 0) {
        size += n;
        if (cap - size - 1 == 0) {
            char *bigger = realloc(data, cap * 2);
            if (bigger == NULL) {
                free(data);
                data = NULL;
                break;
            }
            data = bigger;
            cap *= 2;
        }
    }
    fclose(f);
    if (data) data[size] = '\0';
    if (size_out) *size_out = size;
    return data;
}

static int file_exists(const char *name) {
    char path[512];
    struct stat st;
    work_path(name, path, sizeof path);
    return stat(path, &st) == 0;
}

static void remove_file(const char *name) {
    char path[512];
    work_path(name, path, sizeof path);
    remove(path);
}

/* ---------------------------------------------------------------------------------------- */
/* Running the program */

typedef struct run_result {
    int status; /* exit status, or 128 + signal, or -1 when it could not run or timed out */
    char *out;
    char *err;
} run_result;

static void run_free(run_result *r) {
    free(r->out);
    free(r->err);
    r->out = r->err = NULL;
}

/* Runs `penumbra args...` (args NULL-terminated) in the work folder with a 20 s limit; when
 * interrupt_ms > 0, sends SIGINT once after that many milliseconds. */
static run_result run_cli_interrupted(const char *const *args, long interrupt_ms) {
    run_result r = {-1, NULL, NULL};
    char *argv[64];
    int argc = 0;
    argv[argc++] = (char *)PN_CLI_PATH;
    for (int i = 0; args[i] && argc < 63; i++) argv[argc++] = (char *)args[i];
    argv[argc] = NULL;

    (void)work(); /* create the folder here, not in the child */
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    if (pid < 0) return r;
    if (pid == 0) {
        char out_path[512], err_path[512];
        work_path("cli.stdout", out_path, sizeof out_path);
        work_path("cli.stderr", err_path, sizeof err_path);
        int out_fd = open(out_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        int err_fd = open(err_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        int null_fd = open("/dev/null", O_RDONLY);
        if (out_fd < 0 || err_fd < 0 || null_fd < 0 || chdir(work()) != 0) _exit(126);
        dup2(null_fd, STDIN_FILENO);
        dup2(out_fd, STDOUT_FILENO);
        dup2(err_fd, STDERR_FILENO);
        execv(PN_CLI_PATH, argv);
        _exit(127);
    }
    struct timespec start, now, pause = {0, 5 * 1000 * 1000};
    clock_gettime(CLOCK_MONOTONIC, &start);
    int wstatus = 0, signalled = 0;
    for (;;) {
        pid_t done = waitpid(pid, &wstatus, WNOHANG);
        if (done == pid) break;
        if (done < 0 && errno != EINTR) return r;
        clock_gettime(CLOCK_MONOTONIC, &now);
        long elapsed_ms = (long)(now.tv_sec - start.tv_sec) * 1000 + (long)(now.tv_nsec - start.tv_nsec) / 1000000;
        if (interrupt_ms > 0 && !signalled && elapsed_ms >= interrupt_ms) {
            kill(pid, SIGINT);
            signalled = 1;
        }
        if (now.tv_sec - start.tv_sec > 20) {
            kill(pid, SIGKILL);
            waitpid(pid, &wstatus, 0);
            fprintf(stderr, "  penumbra %s ... timed out\n", args[0] ? args[0] : "");
            r.out = read_file("cli.stdout", NULL);
            r.err = read_file("cli.stderr", NULL);
            return r;
        }
        nanosleep(&pause, NULL);
    }
    if (WIFEXITED(wstatus))
        r.status = WEXITSTATUS(wstatus);
    else if (WIFSIGNALED(wstatus))
        r.status = 128 + WTERMSIG(wstatus);
    r.out = read_file("cli.stdout", NULL);
    r.err = read_file("cli.stderr", NULL);
    if (r.out == NULL) r.out = calloc(1, 1);
    if (r.err == NULL) r.err = calloc(1, 1);
    return r;
}

static run_result run_cli(const char *const *args) {
    return run_cli_interrupted(args, 0);
}

/* Runs and checks the exit status; prints the captured output when it differs. */
#define RUN_EXPECT(result, expected_status, ...)                                                                       \
    do {                                                                                                               \
        const char *const pn_args_[] = {__VA_ARGS__, NULL};                                                            \
        result = run_cli(pn_args_);                                                                                    \
        CHECK_MSG(result.status == (expected_status),                                                                  \
                  "penumbra %s %s: exit %d, expected %d\n  stdout: %s\n  stderr: %s", pn_args_[0],                     \
                  pn_args_[1] ? pn_args_[1] : "", result.status, (expected_status), result.out ? result.out : "",      \
                  result.err ? result.err : "");                                                                       \
    } while (0)

/* ---------------------------------------------------------------------------------------- */
/* Scenes */

/* One quad at z = 0 seen from z = -3, lit by a point light and a small two-sided area light. */
static const char tiny_scene[] = "# tiny test scene\n"
                                 "LookAt 0 0 -3  0 0 0  0 1 0\n"
                                 "Camera \"perspective\" \"float fov\" [ 45 ]\n"
                                 "Film \"rgb\" \"integer xresolution\" [ 16 ] \"integer yresolution\" [ 16 ]\n"
                                 "    \"string filename\" [ \"ignored.exr\" ]\n"
                                 "WorldBegin\n"
                                 "LightSource \"point\" \"point3 from\" [ 0.3 0.2 -1 ] \"rgb I\" [ 1 1 1 ]\n"
                                 "AttributeBegin\n"
                                 "    AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ] \"bool twosided\" true\n"
                                 "    Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ]\n"
                                 "        \"point3 P\" [ -0.6 -0.6 -1  -0.4 -0.6 -1  -0.4 -0.4 -1  -0.6 -0.4 -1 ]\n"
                                 "AttributeEnd\n"
                                 "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
                                 "Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ]\n"
                                 "    \"point3 P\" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ]\n";

static void write_tiny_scene(void) {
    write_file("tiny.pbrt", tiny_scene);
}

/* Renders tiny.pbrt once into tiny.exr for the tests that need an image. */
static int render_tiny(void) {
    static int done = 0, ok = 0;
    if (!done) {
        run_result r;
        done = 1;
        write_tiny_scene();
        RUN_EXPECT(r, 0, "render", "tiny.pbrt", "--spp", "4", "-o", "tiny.exr", "--quiet");
        ok = r.status == 0 && file_exists("tiny.exr");
        run_free(&r);
    }
    return ok;
}

/* ---------------------------------------------------------------------------------------- */
/* Tests */

static void test_version_and_help(void) {
    run_result r;
    RUN_EXPECT(r, 0, "--version");
    CHECK_STR_CONTAINS(r.out, "penumbra " PN_VERSION_STRING);
    run_free(&r);

    RUN_EXPECT(r, 0, "--help");
    CHECK_STR_CONTAINS(r.out, "penumbra render");
    CHECK_STR_CONTAINS(r.out, "penumbra diff");
    CHECK_STR_CONTAINS(r.out, "penumbra info");
    run_free(&r);

    RUN_EXPECT(r, 0, "render", "--help");
    CHECK_STR_CONTAINS(r.out, "--threshold");
    CHECK_STR_CONTAINS(r.out, "--crop");
    run_free(&r);

    RUN_EXPECT(r, 0, "diff", "--help");
    CHECK_STR_CONTAINS(r.out, "--error-image");
    run_free(&r);

    RUN_EXPECT(r, 0, "info", "--help");
    CHECK_STR_CONTAINS(r.out, "usage: penumbra info");
    run_free(&r);

    /* No command at all is a usage error that still shows the help. */
    {
        const char *const none[] = {NULL};
        r = run_cli(none);
        CHECK(r.status == 2);
        CHECK_STR_CONTAINS(r.err, "usage");
        run_free(&r);
    }
}

typedef struct usage_case {
    const char *args[8];
    const char *message;
} usage_case;

static void test_usage_errors(void) {
    static const usage_case cases[] = {
        {{"frobnicate"}, "penumbra: unknown command 'frobnicate'"},
        {{"--frobnicate"}, "unknown option '--frobnicate'"},
        {{"render", "x.pbrt", "--foo"}, "penumbra render: unknown option '--foo' (see penumbra render --help)"},
        {{"render", "x.pbrt", "--spp"}, "option '--spp' needs a value"},
        {{"render", "x.pbrt", "-o"}, "option '-o' needs a value"},
        {{"render", "x.pbrt", "--spp", "abc"}, "invalid value 'abc' for --spp"},
        {{"render", "x.pbrt", "--integrator", "foo"}, "expected 'reference' or 'ias'"},
        {{"render", "x.pbrt", "--integrator", "ias", "--spp", "4"}, "--spp does not apply to ias"},
        {{"render", "x.pbrt", "--cluster-solid-angle", "-1"}, "invalid value '-1' for --cluster-solid-angle"},
        {{"render", "x.pbrt", "--aa-rays", "0"}, "invalid value '0' for --aa-rays"},
        {{"render", "x.pbrt", "--max-passes", "65"}, "invalid value '65' for --max-passes"},
        {{"render", "x.pbrt", "--block-size", "33"}, "invalid value '33' for --block-size"},
        {{"render", "x.pbrt", "--block-size", "4"}, "invalid value '4' for --block-size"},
        {{"render", "x.pbrt", "--env-regions", "x"}, "invalid value 'x' for --env-regions"},
        {{"render", "x.pbrt", "--light-sampler", "tree"}, "expected 'irradiance' or 'bvh'"},
        {{"render", "x.pbrt", "--adaptive-rule", "fast"}, "expected 'auto', 'paper' or 'cross'"},
        {{"render", "x.pbrt", "--integrator", "ias", "--light-sampler", "bvh"}, "applies to the reference integrator"},
        {{"render", "x.pbrt", "--aov-png=yes"}, "--aov-png"},
        {{"illuminance", "x.pbrt", "--grid", "0,0,1,1", "--melanopic"}, "--melanopic needs --spectral"},
        {{"render", "x.pbrt", "--spp", "0"}, "invalid value '0' for --spp"},
        {{"render", "x.pbrt", "--spp", "4x"}, "invalid value '4x' for --spp"},
        {{"render", "x.pbrt", "--spp", "-3"}, "invalid value '-3' for --spp"},
        {{"render", "x.pbrt", "--spp", ""}, "invalid value '' for --spp"},
        {{"render", "x.pbrt", "--spp", "99999999999999999999"}, "for --spp"},
        {{"render", "x.pbrt", "--threshold", "0"}, "for --threshold"},
        {{"render", "x.pbrt", "--threshold", "-0.1"}, "for --threshold"},
        {{"render", "x.pbrt", "--threshold", "nan"}, "for --threshold"},
        {{"render", "x.pbrt", "--threshold", "inf"}, "for --threshold"},
        {{"render", "x.pbrt", "--threshold", "0.01.5"}, "for --threshold"},
        {{"render", "x.pbrt", "--shadow-rays", "0"}, "for --shadow-rays"},
        {{"render", "x.pbrt", "--shadow-rays", "65537"}, "for --shadow-rays"},
        {{"render", "x.pbrt", "--max-samples", "0"}, "for --max-samples"},
        {{"render", "x.pbrt", "--resolution", "16"}, "for --resolution"},
        {{"render", "x.pbrt", "--resolution", "0x16"}, "for --resolution"},
        {{"render", "x.pbrt", "--resolution", "16x"}, "for --resolution"},
        {{"render", "x.pbrt", "--resolution", "16x16x2"}, "for --resolution"},
        {{"render", "x.pbrt", "--resolution", "65537x16"}, "for --resolution"},
        {{"render", "x.pbrt", "--crop", "0.5,0.2,0,1"}, "invalid value '0.5,0.2,0,1' for --crop"},
        {{"render", "x.pbrt", "--crop", "0,1,0"}, "for --crop"},
        {{"render", "x.pbrt", "--crop", "0,1,0,1.5"}, "for --crop"},
        {{"render", "x.pbrt", "--crop", "0,1,0,1,"}, "for --crop"},
        {{"render", "x.pbrt", "--threads", "-1"}, "for --threads"},
        {{"render", "x.pbrt", "--seed", "-1"}, "for --seed"},
        {{"render", "x.pbrt", "--seed", "18446744073709551616"}, "for --seed"},
        {{"render", "x.pbrt", "--exposure", "bright"}, "for --exposure"},
        {{"render", "x.pbrt", "--integrator", "magic"}, "for --integrator"},
        {{"render", "x.pbrt", "--aov", "depth,colour"}, "unknown AOV 'colour'"},
        {{"render", "x.pbrt", "-o", "out.jpg"}, "for -o"},
        {{"render", "x.pbrt", "--png", "out.exr"}, "for --png"},
        {{"render", "x.pbrt", "--spp", "4", "--threshold", "0.1"}, "exclude"},
        {{"render", "x.pbrt", "y.pbrt"}, "unexpected argument 'y.pbrt'"},
        {{"render", "--spp", "4"}, "missing the scene file"},
        {{"render", "x.pbrt", "--quiet=yes"}, "takes no value"},
        {{"diff", "a.exr"}, "needs two images"},
        {{"diff", "a.exr", "b.exr", "--bogus"}, "penumbra diff: unknown option '--bogus'"},
        {{"info"}, "missing the scene file"},
        {{"info", "x.pbrt", "--bogus"}, "penumbra info: unknown option '--bogus'"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        run_result r = run_cli(cases[i].args);
        CHECK_MSG(r.status == 2, "case %zu (%s %s ...): exit %d, stderr: %s", i, cases[i].args[0],
                  cases[i].args[1] ? cases[i].args[1] : "", r.status, r.err ? r.err : "");
        CHECK_STR_CONTAINS(r.err, cases[i].message);
        CHECK_MSG(r.out && r.out[0] == '\0', "case %zu printed to stdout: %s", i, r.out ? r.out : "");
        run_free(&r);
    }
    /* The inline form of a valid option is accepted (it fails later, on the missing scene). */
    run_result r;
    RUN_EXPECT(r, 3, "render", "missing-scene.pbrt", "--spp=4", "--crop=0,0.5,0.25,1");
    CHECK(!file_exists("missing-scene.exr"));
    run_free(&r);
}

typedef struct bad_scene {
    const char *file;
    const char *text;
    const char *location; /* expected "file:line:column:" */
} bad_scene;

static void test_bad_scenes(void) {
    static const bad_scene cases[] = {
        /* An unterminated list: the error points at its opening bracket. */
        {"unterminated.pbrt",
         "WorldBegin\n"
         "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0\n",
         "unterminated.pbrt:2:33:"},
        {"unknown-directive.pbrt",
         "WorldBegin\n"
         "AttributeBegin\n"
         "Foo \"bar\"\n"
         "AttributeEnd\n",
         "unknown-directive.pbrt:3:1:"},
        {"missing-include.pbrt",
         "WorldBegin\n"
         "Include \"does-not-exist.pbrt\"\n",
         "missing-include.pbrt:2:9:"},
        {"missing-ply.pbrt",
         "WorldBegin\n"
         "Shape \"plymesh\"\n"
         "    \"string filename\" [ \"no-such-mesh.ply\" ]\n",
         "missing-ply.pbrt:3:5:"},
        {"wrong-type.pbrt",
         "WorldBegin\n"
         "Shape \"sphere\" \"float radius\" \"abc\"\n",
         "wrong-type.pbrt:2:31:"},
        /* Binary inputs: the scene position of the reference, then "file: message". */
        {"truncated-ply.pbrt",
         "WorldBegin\n"
         "Shape \"plymesh\" \"string filename\" \"trunc.ply\"\n",
         "truncated-ply.pbrt:2:17: trunc.ply: file is too short"},
        {"corrupt-exr.pbrt",
         "WorldBegin\n"
         "Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"corrupt.exr\"\n"
         "Material \"diffuse\" \"texture reflectance\" \"t\"\n"
         "Shape \"sphere\"\n",
         "corrupt-exr.pbrt:2:35: cannot read texture image: corrupt.exr: not a valid EXR file"},
        {"corrupt-png.pbrt",
         "WorldBegin\n"
         "LightSource \"infinite\" \"string filename\" \"corrupt.png\"\n",
         "corrupt-png.pbrt:2:24: cannot read light image: corrupt.png: not a valid PNG file"},
        {"nan-transform.pbrt",
         "Translate 0 0 nan\n"
         "WorldBegin\n",
         "nan-transform.pbrt:1:15: \"nan\" is not a finite number"},
        {"zero-resolution.pbrt",
         "Film \"rgb\" \"integer xresolution\" 0\n"
         "WorldBegin\n",
         "zero-resolution.pbrt:1:12: the film resolution must be between 1 and 65536"},
        {"huge-resolution.pbrt",
         "Film \"rgb\" \"integer xresolution\" 1000000000\n"
         "WorldBegin\n",
         "huge-resolution.pbrt:1:12: the film resolution must be between 1 and 65536"},
    };
    /* Support files of the binary cases: a PLY cut off inside its vertex list, and image files
     * whose contents are not what their names say. */
    write_file("trunc.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                            "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                            "end_header\n0 0 0\n1 0 0\n");
    write_file("corrupt.exr", "this is not an OpenEXR file");
    write_file("corrupt.png", "\x89PNG\r\n\x1a\nnot really");
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        write_file(cases[i].file, cases[i].text);
        const char *const args[] = {"render", cases[i].file, "--spp",   "1",        "-o", "bad.exr",
                                    "--png",  "bad.png",     "--stats", "bad.json", NULL};
        run_result r = run_cli(args);
        CHECK_MSG(r.status == 3, "%s: exit %d, stderr: %s", cases[i].file, r.status, r.err ? r.err : "");
        CHECK_STR_CONTAINS(r.err, cases[i].location);
        CHECK_STR_CONTAINS(r.err, "penumbra: ");
        CHECK(!file_exists("bad.exr"));
        CHECK(!file_exists("bad.png"));
        CHECK(!file_exists("bad.json"));
        run_free(&r);

        /* Without -o nothing named after the scene appears either; info fails the same way. */
        char default_name[128];
        snprintf(default_name, sizeof default_name, "%.*s.exr", (int)(strlen(cases[i].file) - 5), cases[i].file);
        const char *const args2[] = {"render", cases[i].file, "--spp", "1", NULL};
        r = run_cli(args2);
        CHECK(r.status == 3);
        CHECK(!file_exists(default_name));
        run_free(&r);
        const char *const args3[] = {"info", cases[i].file, NULL};
        r = run_cli(args3);
        CHECK(r.status == 3);
        CHECK_STR_CONTAINS(r.err, cases[i].location);
        run_free(&r);
    }
    /* A scene file that does not exist at all. */
    run_result r;
    RUN_EXPECT(r, 3, "render", "nowhere.pbrt", "-o", "nowhere.exr");
    CHECK_STR_CONTAINS(r.err, "nowhere.pbrt");
    CHECK(!file_exists("nowhere.exr"));
    run_free(&r);
}

static void test_render_outputs(void) {
    run_result r;
    write_tiny_scene();
    char out_dir[512];
    work_path("out", out_dir, sizeof out_dir);
    mkdir(out_dir, 0755);
    RUN_EXPECT(r, 0, "render", "tiny.pbrt", "--spp", "4", "-o", "out/full.exr", "--png", "out/full.png", "--stats",
               "out/full.json", "--aov", "all", "--threads", "2", "--seed", "7");
    CHECK_STR_CONTAINS(r.out, "16x16");
    CHECK_STR_CONTAINS(r.out, "shadow rays");
    CHECK_STR_CONTAINS(r.out, "out/full.exr");
    run_free(&r);

    size_t size = 0;
    char *exr = read_file("out/full.exr", &size);
    CHECK(exr != NULL && size > 4 && (unsigned char)exr[0] == 0x76 && (unsigned char)exr[1] == 0x2f &&
          (unsigned char)exr[2] == 0x31 && (unsigned char)exr[3] == 0x01);
    free(exr);
    char *png = read_file("out/full.png", &size);
    CHECK(png != NULL && size > 8 && memcmp(png, "\x89PNG", 4) == 0);
    free(png);
    char *json = read_file("out/full.json", &size);
    CHECK(json != NULL);
    if (json) {
        CHECK_STR_CONTAINS(json, "\"shadow_rays\"");
        CHECK_STR_CONTAINS(json, "\"penumbra_version\": \"" PN_VERSION_STRING "\"");
        CHECK_STR_CONTAINS(json, "\"scene\": \"tiny.pbrt\"");
        CHECK_STR_CONTAINS(json, "\"lights\"");
        CHECK(json[0] == '{' && size >= 2 && json[size - 2] == '}');
    }
    free(json);
    CHECK(!file_exists("out/full.json.tmp"));

    /* Default output name, and --quiet prints nothing on stdout. */
    remove_file("tiny.exr");
    RUN_EXPECT(r, 0, "render", "tiny.pbrt", "--spp", "1", "--quiet", "--crop", "0.25,0.75,0,0.5");
    CHECK(file_exists("tiny.exr"));
    CHECK(r.out && r.out[0] == '\0');
    run_free(&r);
    remove_file("tiny.exr");

    /* ias: its statistics layers as false-colour PNGs, its tables in the JSON. */
    RUN_EXPECT(r, 0, "render", "tiny.pbrt", "--integrator", "ias", "-o", "out/ias.exr", "--aov",
               "passes,visible_fraction", "--aov-png", "--stats", "out/ias.json", "--quiet");
    run_free(&r);
    char *fc = read_file("out/ias.passes.png", &size);
    CHECK(fc != NULL && size > 8 && memcmp(fc, "\x89PNG", 4) == 0);
    free(fc);
    CHECK(file_exists("out/ias.visible_fraction.png"));
    json = read_file("out/ias.json", &size);
    CHECK(json != NULL);
    if (json) {
        CHECK_STR_CONTAINS(json, "\"integrator\": \"ias\"");
        CHECK_STR_CONTAINS(json, "\"passes_per_pixel_mean\"");
        CHECK_STR_CONTAINS(json, "\"lights_visible_viewpoint\"");
    }
    free(json);
}

static void test_info(void) {
    run_result r;
    write_tiny_scene();
    RUN_EXPECT(r, 0, "info", "tiny.pbrt");
    CHECK_STR_CONTAINS(r.out, "lights");
    CHECK_STR_CONTAINS(r.out, "point        1");
    CHECK_STR_CONTAINS(r.out, "triangles");
    CHECK_STR_CONTAINS(r.out, "materials");
    CHECK_STR_CONTAINS(r.out, "16x16");
    run_free(&r);
}

/* Value printed after `label` on its own line of `text`, or NAN. */
static double printed_value(const char *text, const char *label) {
    const char *p = text ? strstr(text, label) : NULL;
    if (p == NULL) return NAN;
    return strtod(p + strlen(label), NULL);
}

static void test_diff(void) {
    run_result r;
    if (!render_tiny()) {
        CHECK_MSG(0, "could not render tiny.pbrt");
        return;
    }
    RUN_EXPECT(r, 0, "diff", "tiny.exr", "tiny.exr", "--error-image", "err.exr");
    CHECK_STR_CONTAINS(r.out, "epsilon 0.01");
    CHECK(printed_value(r.out, "\nrelMSE") == 0.0);
    CHECK(printed_value(r.out, "\nRMSE") == 0.0);
    CHECK(file_exists("err.exr"));
    run_free(&r);

    RUN_EXPECT(r, 0, "diff", "tiny.exr", "tiny.exr", "--json");
    CHECK_STR_CONTAINS(r.out, "\"relmse\": 0");
    CHECK_STR_CONTAINS(r.out, "\"relmse_epsilon\": 0.01");
    run_free(&r);

    /* Images of different sizes cannot be compared. */
    RUN_EXPECT(r, 0, "render", "tiny.pbrt", "--spp", "1", "--resolution", "8x8", "-o", "small.exr", "--quiet");
    run_free(&r);
    RUN_EXPECT(r, 3, "diff", "tiny.exr", "small.exr", "--error-image", "err2.exr");
    CHECK_STR_CONTAINS(r.err, "differ");
    CHECK(!file_exists("err2.exr"));
    run_free(&r);

    /* A missing image is bad input. */
    RUN_EXPECT(r, 3, "diff", "tiny.exr", "no-such-image.exr");
    CHECK_STR_CONTAINS(r.err, "no-such-image.exr");
    run_free(&r);
}

static void test_same_image_for_any_thread_count(void) {
    run_result r;
    write_tiny_scene();
    RUN_EXPECT(r, 0, "render", "tiny.pbrt", "--threshold", "0.05", "--threads", "1", "--seed", "3", "-o", "t1.exr",
               "--quiet");
    run_free(&r);
    RUN_EXPECT(r, 0, "render", "tiny.pbrt", "--threshold", "0.05", "--threads", "2", "--seed", "3", "-o", "t2.exr",
               "--quiet");
    run_free(&r);
    RUN_EXPECT(r, 0, "diff", "t1.exr", "t2.exr");
    CHECK(printed_value(r.out, "\nRMSE") == 0.0);
    run_free(&r);
}

/* Ctrl-C: exit status 130 and nothing at the -o path (the partial image goes elsewhere). */
static void test_interrupt(void) {
    write_file("slow.pbrt", tiny_scene);
    const char *const args[] = {"render", "slow.pbrt", "--resolution", "1024x1024", "--spp",     "4096", "--threads",
                                "2",      "-o",        "slow.exr",     "--stats",   "slow.json", NULL};
    run_result r = run_cli_interrupted(args, 400);
    CHECK_MSG(r.status == 130, "exit %d, stderr: %s", r.status, r.err ? r.err : "");
    CHECK(!file_exists("slow.exr"));
    CHECK(!file_exists("slow.exr.tmp"));
    if (r.err && strstr(r.err, "interrupted")) {
        /* The handler was installed (the render had started): the partial image is kept aside
         * and the statistics say it is partial. */
        CHECK_STR_CONTAINS(r.err, "not written to 'slow.exr'");
        CHECK(file_exists("slow.partial.exr"));
        char *json = read_file("slow.json", NULL);
        CHECK(json != NULL);
        if (json) CHECK_STR_CONTAINS(json, "\"partial\": true");
        free(json);
    }
    run_free(&r);
}

static void test_unwritable_output(void) {
    run_result r;
    write_tiny_scene();
    write_file("unwritable.pbrt", tiny_scene);
    RUN_EXPECT(r, 4, "render", "unwritable.pbrt", "--spp", "1", "-o", "no-such-dir/out.exr");
    CHECK_STR_CONTAINS(r.err, "no-such-dir/out.exr");
    CHECK(!file_exists("no-such-dir"));
    CHECK(!file_exists("unwritable.exr"));
    run_free(&r);

    RUN_EXPECT(r, 4, "render", "tiny.pbrt", "--spp", "1", "-o", "ok.exr", "--stats", "no-such-dir/stats.json");
    CHECK(!file_exists("ok.exr"));
    run_free(&r);

    if (!render_tiny()) return;
    RUN_EXPECT(r, 4, "diff", "tiny.exr", "tiny.exr", "--error-image", "no-such-dir/err.exr");
    run_free(&r);
}

PN_TESTS(TEST(test_version_and_help), TEST(test_usage_errors), TEST(test_bad_scenes), TEST(test_render_outputs),
         TEST(test_info), TEST(test_diff), TEST(test_same_image_for_any_thread_count), TEST(test_interrupt),
         TEST(test_unwritable_output))
