/* fuzz_common.c — the input file and context of the fuzz targets (fuzz_common.h). */
#ifndef _DEFAULT_SOURCE
#define _DEFAULT_SOURCE /* mkdtemp */
#endif
#include "fuzz_common.h"

#include <dirent.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char pn_fuzz_dir[64];

static void pn_fuzz_remove_dir(void) {
    DIR *dir = opendir(pn_fuzz_dir);
    struct dirent *e;
    char path[512];
    while (dir && (e = readdir(dir)) != NULL) {
        if (e->d_name[0] == '.' && (e->d_name[1] == '\0' || (e->d_name[1] == '.' && e->d_name[2] == '\0'))) continue;
        snprintf(path, sizeof path, "%s/%s", pn_fuzz_dir, e->d_name);
        unlink(path);
    }
    if (dir) closedir(dir);
    rmdir(pn_fuzz_dir);
}

const char *pn_fuzz_write_input(const char *name, const uint8_t *data, size_t size) {
    static char path[512];
    if (!pn_fuzz_dir[0]) {
        const char *tmp = getenv("TMPDIR");
        snprintf(pn_fuzz_dir, sizeof pn_fuzz_dir, "%s/pn-fuzz-XXXXXX",
                 tmp && tmp[0] && strlen(tmp) < 40 ? tmp : "/tmp");
        if (!mkdtemp(pn_fuzz_dir)) {
            pn_fuzz_dir[0] = '\0';
            return NULL;
        }
        atexit(pn_fuzz_remove_dir);
    }
    snprintf(path, sizeof path, "%s/%s", pn_fuzz_dir, name);
    FILE *f = fopen(path, "wb");
    if (!f) return NULL;
    int ok = fwrite(data, 1, size, f) == size;
    ok = fclose(f) == 0 && ok;
    return ok ? path : NULL;
}

pn_context pn_fuzz_context(void) {
    static pn_context ctx;
    if (!ctx) ctx = pn_context_new();
    return ctx;
}
