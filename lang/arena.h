/* arena.h - bump allocator owning everything of one compile session (AST nodes,
 * interned names, IR). Freed all at once with arena_free(); nothing in it is freed
 * individually, so error paths cannot leak.
 */
#ifndef FREP_ARENA_H
#define FREP_ARENA_H

#include <stddef.h>

typedef struct arena_chunk arena_chunk;

typedef struct arena {
    arena_chunk *head;
    int failed;          /* an allocation failed: results are unusable */
} arena;

void arena_init(arena *A);
void arena_free(arena *A);
/* Zeroed memory aligned for any type; NULL (and A->failed set) when out of memory. */
void *arena_alloc(arena *A, size_t size);
/* Copy of s[0..n) with a NUL appended. */
char *arena_strndup(arena *A, const char *s, size_t n);
/* Grow an arena array: returns a copy with room for new_cap elements. */
void *arena_grow(arena *A, void *old, size_t old_count, size_t new_cap, size_t elem);

#endif
