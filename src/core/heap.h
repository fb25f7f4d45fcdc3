/* heap.h — a binary heap of (key, payload) entries: the priority queue of the greedy builds and
 * refinement loops (cluster tree build and capped cut, lightcuts, environment regions, the
 * painter and dcm drivers).
 *
 * Order: PN_HEAP_MAX pops the largest key first, PN_HEAP_MIN the smallest. Keys are compared
 * with < and > only, so a NaN key is never before anything (push none where the order matters).
 *
 * Ties (equal keys) follow one of two explicit rules:
 *  - with PN_HEAP_TIES_BY_PAYLOAD the smaller payload leaves first, whatever the history, so
 *    with distinct payloads the pop sequence is a function of the entries alone (callers with
 *    several tie keys pack them into the 64-bit payload);
 *  - without it, ties leave in the order the classic array sift gives, which depends on the
 *    sequence of pushes and pops (deterministic, but neither FIFO nor LIFO): a pushed entry
 *    rises past parents it is strictly before; a pop moves the last entry down from the root,
 *    past the child that is first (the right one only when strictly before the left) as long as
 *    that child is strictly before it. The array itself (entries[0 .. count)) is thus the same
 *    as that of any hand-written heap with this sift, which some callers read in array order.
 */
#ifndef PN_CORE_HEAP_H
#define PN_CORE_HEAP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct pn_heap_entry {
    double key;
    int64_t payload;
} pn_heap_entry;

enum {
    PN_HEAP_MAX = 0,             /* the largest key first */
    PN_HEAP_MIN = 1,             /* the smallest key first */
    PN_HEAP_TIES_BY_PAYLOAD = 2, /* equal keys: the smaller payload first */
};

typedef struct pn_heap {
    pn_heap_entry *entries; /* [0, count): the heap, entries[0] first */
    size_t count, capacity;
    int flags;
    bool fixed; /* storage is the caller's: never grown or freed */
} pn_heap;

/* An empty heap that grows as needed (free with pn_heap_free). */
void pn_heap_init(pn_heap *h, int flags);
/* An empty heap in the caller's storage of `capacity` entries: a push beyond it fails. */
void pn_heap_init_fixed(pn_heap *h, int flags, pn_heap_entry *storage, size_t capacity);
void pn_heap_free(pn_heap *h);
/* Room for n entries without a further allocation; false when out of memory (or fixed). */
bool pn_heap_reserve(pn_heap *h, size_t n);

static inline void pn_heap_clear(pn_heap *h) {
    h->count = 0;
}

/* The first entry, not removed; the heap must not be empty. */
static inline pn_heap_entry pn_heap_top(const pn_heap *h) {
    return h->entries[0];
}

/* ---- push and pop, inline: the capped cut and the cluster build spend much of their time here */

/* Whether x leaves before y: strictly, so equal entries are never before each other. The sifts
 * below are inlined with constant min and ties, one copy an order (the comparison is the hot part
 * of pn_cluster_cut_capped). */
static inline bool pn_heap_before_(bool min, bool ties, const pn_heap_entry *x, const pn_heap_entry *y) {
    if (x->key != y->key) return min ? x->key < y->key : x->key > y->key;
    return ties && x->payload < y->payload;
}

/* Puts x at hole i, moving it up past the parents it is before. */
static inline void pn_heap_sift_up_(pn_heap_entry *e, size_t i, pn_heap_entry x, bool min, bool ties) {
    while (i > 0) {
        size_t parent = (i - 1) / 2;
        if (!pn_heap_before_(min, ties, &x, &e[parent])) break;
        e[i] = e[parent];
        i = parent;
    }
    e[i] = x;
}

/* Puts x at the root hole of e[0, n), moving it down past the first child while that is before
 * it (the right child only when it is before the left). */
static inline void pn_heap_sift_down_(pn_heap_entry *e, size_t n, pn_heap_entry x, bool min, bool ties) {
    size_t i = 0;
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n && pn_heap_before_(min, ties, &e[c + 1], &e[c])) c++;
        if (!pn_heap_before_(min, ties, &e[c], &x)) break;
        e[i] = e[c];
        i = c;
    }
    e[i] = x;
}

/* False when out of memory (or a fixed heap is full); the heap is then unchanged. */
static inline bool pn_heap_push(pn_heap *h, double key, int64_t payload) {
    if (h->count == h->capacity && !pn_heap_reserve(h, h->capacity ? 2 * h->capacity : 64)) return false;
    const pn_heap_entry x = {key, payload};
    const size_t i = h->count++;
    switch (h->flags & (PN_HEAP_MIN | PN_HEAP_TIES_BY_PAYLOAD)) {
    case PN_HEAP_MAX: pn_heap_sift_up_(h->entries, i, x, false, false); break;
    case PN_HEAP_MIN: pn_heap_sift_up_(h->entries, i, x, true, false); break;
    case PN_HEAP_TIES_BY_PAYLOAD: pn_heap_sift_up_(h->entries, i, x, false, true); break;
    default: pn_heap_sift_up_(h->entries, i, x, true, true); break;
    }
    return true;
}

/* Removes and returns the first entry; the heap must not be empty. */
static inline pn_heap_entry pn_heap_pop(pn_heap *h) {
    const pn_heap_entry top = h->entries[0], last = h->entries[--h->count];
    const size_t n = h->count;
    if (n == 0) return top;
    switch (h->flags & (PN_HEAP_MIN | PN_HEAP_TIES_BY_PAYLOAD)) {
    case PN_HEAP_MAX: pn_heap_sift_down_(h->entries, n, last, false, false); break;
    case PN_HEAP_MIN: pn_heap_sift_down_(h->entries, n, last, true, false); break;
    case PN_HEAP_TIES_BY_PAYLOAD: pn_heap_sift_down_(h->entries, n, last, false, true); break;
    default: pn_heap_sift_down_(h->entries, n, last, true, true); break;
    }
    return top;
}

#endif
