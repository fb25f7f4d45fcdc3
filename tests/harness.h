/* harness.h — penumbra's tiny test harness: CHECK macros, a test table, a summary line.
 *
 * A test file defines functions `static void test_name(void)` and a table
 *   PN_TESTS(TEST(test_name), TEST(other))
 * which expands to main(). Each test binary prints "N passed, N failed" and exits non-zero on
 * failure. Tests that need ../shared call pn_test_skip("why") and count as skipped.
 * A scratch folder handed to pn_test_remove_at_end is removed with its contents when every case
 * passed (kept after a failure, for inspection).
 */
#ifndef PN_TEST_HARNESS_H
#define PN_TEST_HARNESS_H

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct pn_test_case {
    const char *name;
    void (*fn)(void);
} pn_test_case;

static int pn_test_failures_in_case;
static int pn_test_skipped_case;

#define CHECK(cond)                                                                                                    \
    do {                                                                                                               \
        if (!(cond)) {                                                                                                 \
            fprintf(stderr, "  %s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);                                 \
            pn_test_failures_in_case++;                                                                                \
        }                                                                                                              \
    } while (0)

#define CHECK_MSG(cond, ...)                                                                                           \
    do {                                                                                                               \
        if (!(cond)) {                                                                                                 \
            fprintf(stderr, "  %s:%d: CHECK failed: %s: ", __FILE__, __LINE__, #cond);                                 \
            fprintf(stderr, __VA_ARGS__);                                                                              \
            fputc('\n', stderr);                                                                                       \
            pn_test_failures_in_case++;                                                                                \
        }                                                                                                              \
    } while (0)

#define CHECK_NEAR(a, b, tol)                                                                                          \
    do {                                                                                                               \
        double pn_a_ = (double)(a), pn_b_ = (double)(b), pn_t_ = (double)(tol);                                        \
        if (!(fabs(pn_a_ - pn_b_) <= pn_t_)) {                                                                         \
            fprintf(stderr, "  %s:%d: CHECK_NEAR failed: %s = %.9g, %s = %.9g, tol %.3g\n", __FILE__, __LINE__, #a,    \
                    pn_a_, #b, pn_b_, pn_t_);                                                                          \
            pn_test_failures_in_case++;                                                                                \
        }                                                                                                              \
    } while (0)

#define CHECK_STR_CONTAINS(haystack, needle)                                                                           \
    do {                                                                                                               \
        const char *pn_h_ = (haystack), *pn_n_ = (needle);                                                             \
        if (pn_h_ == NULL || strstr(pn_h_, pn_n_) == NULL) {                                                           \
            fprintf(stderr, "  %s:%d: expected \"%s\" to contain \"%s\"\n", __FILE__, __LINE__,                        \
                    pn_h_ ? pn_h_ : "(null)", pn_n_);                                                                  \
            pn_test_failures_in_case++;                                                                                \
        }                                                                                                              \
    } while (0)

static inline void pn_test_skip(const char *why) {
    fprintf(stderr, "  skipped: %s\n", why);
    pn_test_skipped_case = 1;
}

/* Removes path and, for a folder, everything below it; symbolic links are removed, not followed. */
static inline void pn_test_remove_tree(const char *path) {
    struct stat st;
    if (lstat(path, &st) != 0) return;
    if (S_ISDIR(st.st_mode)) {
        DIR *d = opendir(path);
        if (d) {
            struct dirent *e;
            while ((e = readdir(d)) != NULL) {
                if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
                char child[1024];
                if ((size_t)snprintf(child, sizeof child, "%s/%s", path, e->d_name) < sizeof child)
                    pn_test_remove_tree(child);
            }
            closedir(d);
        }
        rmdir(path);
    } else {
        unlink(path);
    }
}

static char pn_test_scratch[8][256];
static int pn_test_scratch_count;

/* Registers a scratch folder (made by the test, under /tmp) for removal at the end. */
static inline void pn_test_remove_at_end(const char *dir) {
    if (dir && dir[0] && strncmp(dir, "/tmp/", 5) == 0 && pn_test_scratch_count < 8 &&
        strlen(dir) < sizeof pn_test_scratch[0])
        strcpy(pn_test_scratch[pn_test_scratch_count++], dir);
}

#define TEST(fn)                                                                                                       \
    { #fn, fn }

#define PN_TESTS(...)                                                                                                  \
    int main(void) {                                                                                                   \
        static const pn_test_case cases[] = {__VA_ARGS__};                                                             \
        int passed = 0, failed = 0, skipped = 0;                                                                       \
        for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {                                                  \
            pn_test_failures_in_case = 0;                                                                              \
            pn_test_skipped_case = 0;                                                                                  \
            fprintf(stderr, "[ RUN  ] %s\n", cases[i].name);                                                           \
            cases[i].fn();                                                                                             \
            if (pn_test_failures_in_case) {                                                                            \
                failed++;                                                                                              \
                fprintf(stderr, "[ FAIL ] %s\n", cases[i].name);                                                       \
            } else if (pn_test_skipped_case) {                                                                         \
                skipped++;                                                                                             \
                fprintf(stderr, "[ SKIP ] %s\n", cases[i].name);                                                       \
            } else {                                                                                                   \
                passed++;                                                                                              \
                fprintf(stderr, "[  OK  ] %s\n", cases[i].name);                                                       \
            }                                                                                                          \
        }                                                                                                              \
        printf("%d passed, %d failed, %d skipped\n", passed, failed, skipped);                                         \
        if (!failed)                                                                                                   \
            for (int d = 0; d < pn_test_scratch_count; d++) pn_test_remove_tree(pn_test_scratch[d]);                   \
        /* 77: CTest reports the test as skipped (SKIP_RETURN_CODE) when nothing ran. */                               \
        return failed ? 1 : (passed == 0 && skipped > 0 ? 77 : 0);                                                     \
    }

/* Writes `text` to dir/name and returns the path (static storage, valid until the next call),
 * or NULL if the file cannot be written. */
static inline const char *pn_test_write_file(const char *dir, const char *name, const char *text) {
    static char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    if (!f) return NULL;
    fputs(text, f);
    fclose(f);
    return path;
}

/* Path of the shared data folder (../shared from the source tree), or NULL if absent. */
#ifndef PN_SHARED_DIR
#define PN_SHARED_DIR ""
#endif
#ifndef PN_SOURCE_DIR
#define PN_SOURCE_DIR "."
#endif

#endif
