/* alloc_hook.c — the counting allocation wrappers of alloc_hook.h (sanitizer test build only).
 * The counter is process-wide (a test instrument, not library state): atomic, because the
 * render's worker threads allocate too. */
#define PN_ALLOC_HOOK_IMPLEMENTATION
#include "core/alloc_hook.h"

/* The header is also forced in front of this file (-include), macros and all: the wrappers
 * below call the C library's functions. */
#undef malloc
#undef calloc
#undef realloc
#undef strdup

#include <errno.h>
#include <stdatomic.h>

static atomic_long pn_alloc_calls;
static atomic_long pn_alloc_fail_target;
static atomic_int pn_alloc_did_fail;

/* Counts one allocation; 1 when this is the one to fail. */
static int pn_alloc_should_fail(void) {
    long n = atomic_fetch_add(&pn_alloc_calls, 1) + 1;
    long target = atomic_load(&pn_alloc_fail_target);
    if (target > 0 && n == target) {
        atomic_store(&pn_alloc_did_fail, 1);
        errno = ENOMEM;
        return 1;
    }
    return 0;
}

void *pn_alloc_hook_malloc(size_t size) {
    return pn_alloc_should_fail() ? NULL : malloc(size);
}

void *pn_alloc_hook_calloc(size_t count, size_t size) {
    return pn_alloc_should_fail() ? NULL : calloc(count, size);
}

void *pn_alloc_hook_realloc(void *pointer, size_t size) {
    return pn_alloc_should_fail() ? NULL : realloc(pointer, size);
}

char *pn_alloc_hook_strdup(const char *text) {
    return pn_alloc_should_fail() ? NULL : strdup(text);
}

void pn_alloc_hook_fail_at(long n) {
    atomic_store(&pn_alloc_calls, 0);
    atomic_store(&pn_alloc_did_fail, 0);
    atomic_store(&pn_alloc_fail_target, n);
}

long pn_alloc_hook_count(void) {
    return atomic_load(&pn_alloc_calls);
}

int pn_alloc_hook_failed(void) {
    return atomic_load(&pn_alloc_did_fail);
}
