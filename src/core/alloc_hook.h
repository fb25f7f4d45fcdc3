/* alloc_hook.h — allocation-failure injection for the sanitizer test build (issue 19; the
 * SQLite/Lua practice). With PN_ALLOC_HOOK (set by PN_SANITIZE, i.e. `make sanitize`) CMake
 * forces this header into every library source (-include), so that each malloc, calloc, realloc
 * and strdup of the library goes through the counting wrappers of core/alloc_hook.c, which can
 * make the N-th allocation fail. test_alloc_failures sweeps N over loading the demo scene and a
 * small render and checks that each failure gives an error status, no crash and no leak.
 *
 * A forced macro rather than pn_malloc calls written into every file: it covers every
 * allocation of the library (scene loader, render paths, readers, stb's decoders) without
 * touching the files of every module, and release builds are not changed at all. */
#ifndef PN_CORE_ALLOC_HOOK_H
#define PN_CORE_ALLOC_HOOK_H

#include <stddef.h>
#include <stdlib.h>
#include <string.h>

void *pn_alloc_hook_malloc(size_t size);
void *pn_alloc_hook_calloc(size_t count, size_t size);
void *pn_alloc_hook_realloc(void *pointer, size_t size);
char *pn_alloc_hook_strdup(const char *text);

/* Makes the allocation `n` calls from now fail (1 = the next one); 0 disables injection.
 * Counting restarts at every call. */
void pn_alloc_hook_fail_at(long n);
/* Allocations counted since the last pn_alloc_hook_fail_at, and whether the injected failure
 * has happened. */
long pn_alloc_hook_count(void);
int pn_alloc_hook_failed(void);

#ifndef PN_ALLOC_HOOK_IMPLEMENTATION
#define malloc(size) pn_alloc_hook_malloc(size)
#define calloc(count, size) pn_alloc_hook_calloc(count, size)
#define realloc(pointer, size) pn_alloc_hook_realloc(pointer, size)
#define strdup(text) pn_alloc_hook_strdup(text)
#endif

#endif
