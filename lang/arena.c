/* arena.c - bump allocator of a compile session (see arena.h). */
#include "alloc.h"
#include "arena.h"

#include <stdlib.h>
#include <string.h>

#define ARENA_CHUNK_MIN (64u * 1024u) /* small chunks would make many mallocs */

struct arena_chunk {
    arena_chunk *next;
    size_t used, cap;
    _Alignas(max_align_t) unsigned char data[];
};

void arena_init(arena *A) { A->head = NULL; A->failed = 0; }

void arena_free(arena *A)
{
    arena_chunk *c = A->head;
    while (c) {
        arena_chunk *n = c->next;
        frep_free(c);
        c = n;
    }
    A->head = NULL;
}

void *arena_alloc(arena *A, size_t size)
{
    const size_t align = _Alignof(max_align_t);
    size = (size + align - 1) & ~(align - 1);
    if (size == 0) size = align;
    arena_chunk *c = A->head;
    if (!c || c->cap - c->used < size) {
        size_t cap = size > ARENA_CHUNK_MIN ? size : ARENA_CHUNK_MIN;
        c = frep_malloc(sizeof *c + cap);
        if (!c) { A->failed = 1; return NULL; }
        c->used = 0;
        c->cap = cap;
        c->next = A->head;
        A->head = c;
    }
    void *p = c->data + c->used;
    c->used += size;
    memset(p, 0, size);
    return p;
}

char *arena_strndup(arena *A, const char *s, size_t n)
{
    char *p = arena_alloc(A, n + 1);
    if (!p) return NULL;
    memcpy(p, s, n);
    p[n] = '\0';
    return p;
}

void *arena_grow(arena *A, void *old, size_t old_count, size_t new_cap, size_t elem)
{
    void *p = arena_alloc(A, new_cap * elem);
    if (p && old && old_count) memcpy(p, old, old_count * elem);
    return p;
}
