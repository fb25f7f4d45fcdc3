/* heap.c — the binary heap of core/heap.h (the sift and tie rules are stated there). */
#include "core/heap.h"

#include <stdlib.h>

/* Whether x leaves before y: strictly, so equal entries are never before each other. */
static inline bool before(int flags, const pn_heap_entry *x, const pn_heap_entry *y) {
    if (x->key != y->key) return (flags & PN_HEAP_MIN) ? x->key < y->key : x->key > y->key;
    return (flags & PN_HEAP_TIES_BY_PAYLOAD) && x->payload < y->payload;
}

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

bool pn_heap_push(pn_heap *h, double key, int64_t payload) {
    if (h->count == h->capacity && !pn_heap_reserve(h, h->capacity ? 2 * h->capacity : 64)) return false;
    const pn_heap_entry x = {key, payload};
    pn_heap_entry *e = h->entries;
    size_t i = h->count++;
    while (i > 0) {
        size_t parent = (i - 1) / 2;
        if (!before(h->flags, &x, &e[parent])) break;
        e[i] = e[parent];
        i = parent;
    }
    e[i] = x;
    return true;
}

pn_heap_entry pn_heap_pop(pn_heap *h) {
    pn_heap_entry *e = h->entries;
    const pn_heap_entry top = e[0], last = e[--h->count];
    const size_t n = h->count;
    size_t i = 0;
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n && before(h->flags, &e[c + 1], &e[c])) c++;
        if (!before(h->flags, &e[c], &last)) break;
        e[i] = e[c];
        i = c;
    }
    if (n > 0) e[i] = last;
    return top;
}
