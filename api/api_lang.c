/* api_lang.c - the language jobs of the public API that are not compiling: the
 * canonical source of a file (lang/print.c's re-print of the parsed tree, as
 * `frep print` shows it).
 */
#include "config.h"

#include "api.h"
#include "arena.h"
#include "ast.h"
#include "check.h"

#include <string.h>

char *frep_print_source(const char *file, const char *text, size_t len, int strict,
                        size_t *out_len, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    diag_sink ds = { diag, user, file, 0, 0, NULL, 0 };
    arena A;
    arena_init(&A);
    ast_file f;
    char *out = NULL;
    if (text && ast_parse(&A, file, text, len, &ds, &f) == 0) {
        /* printed before checking: the check annotates the tree */
        out = ast_print(&f);
        if (!out) api_report(&d, FREP_ERROR, "out of memory");
        check_info ci;
        if (out && strict && (check_file(&A, &f, 1, &ds, &ci) != 0 || ds.errors)) {
            frep_free(out);
            out = NULL;
        }
    }
    arena_free(&A);
    if (out_len) *out_len = out ? strlen(out) : 0;
    return out;
}
