/* scene_files.h — helpers of the tests that write scene files into a temporary folder and parse
 * them: a context that logs nothing, the folder (made once per test program, named after
 * PN_SCENE_FILES_PREFIX, which the test defines before including this header), paths inside it,
 * and writing a file there (one level of sub-folder created when the name has one). */
#ifndef PN_TESTS_SCENE_FILES_H
#define PN_TESTS_SCENE_FILES_H

#include "penumbra/penumbra.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#ifndef PN_SCENE_FILES_PREFIX
#error "define PN_SCENE_FILES_PREFIX (e.g. \"pn_test_parser\") before including scene_files.h"
#endif

static inline void silent_log(void *user, pn_log_level level, const char *message) {
    (void)user;
    (void)level;
    (void)message;
}

static inline pn_context test_context(void) {
    static pn_context ctx;
    if (!ctx) {
        ctx = pn_context_new();
        pn_context_set_log(ctx, silent_log, NULL);
    }
    return ctx;
}

static inline const char *temp_dir(void) {
    static char dir[96];
    if (!dir[0]) {
        snprintf(dir, sizeof dir, "/tmp/%s_XXXXXX", PN_SCENE_FILES_PREFIX);
        if (!mkdtemp(dir)) {
            fprintf(stderr, "mkdtemp failed: %s\n", strerror(errno));
            exit(1);
        }
        pn_test_remove_at_end(dir);
    }
    return dir;
}

/* Absolute path of `rel` inside the temp folder (a static buffer per call, 8 in rotation). */
static inline const char *tpath(const char *rel) {
    static char bufs[8][512];
    static int next;
    char *b = bufs[next++ % 8];
    snprintf(b, 512, "%s/%s", temp_dir(), rel);
    return b;
}

static inline void write_file(const char *rel, const char *text) {
    char path[512];
    snprintf(path, sizeof path, "%s", tpath(rel));
    /* create one level of sub-folder when needed */
    char *slash = strrchr(path, '/');
    if (slash) {
        *slash = '\0';
        mkdir(path, 0755);
        *slash = '/';
    }
    FILE *f = fopen(path, "wb");
    if (!f) {
        fprintf(stderr, "cannot write %s\n", path);
        exit(1);
    }
    fputs(text, f);
    fclose(f);
}

#endif
