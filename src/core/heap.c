/* heap.c — the binary heap of core/heap.h (the sift and tie rules are stated there). */
#include "core/heap.h"

#include <stdlib.h>

void pn_heap_init(pn_heap *h, int flags) {
    *h = (pn_heap){NULL, 0, 0, flags, false};
}

void pn_heap_init_fixed(pn_heap *h, int flags, pn_heap_entry *storage, size_t capacity) {
    *h = (pn_heap){storage, 0, capacity, flags, true};
}

void pn_heap_free(pn_heap *h) {
    if (!h->fixed) free(h->entries);
    pn_heap_init(h, h->flags);
}

bool pn_heap_reserve(pn_heap *h, size_t n) {
    if (n <= h->capacity) return true;
    if (h->fixed) return false;
    pn_heap_entry *e = realloc(h->entries, n * sizeof *e);
    if (!e) return false;
    h->entries = e;
    h->capacity = n;
    return true;
}
