/* Runs an exported model's compensator on a reference read from stdin and prints the commanded currents, one
 * per line, as exact hexadecimal doubles. Usage: run_model DT_S < "n\n ref theta\n ..." (compiled with the header
 * `bmr export MODEL --c model.h` wrote, `include/bmr.h` and the bmr static library). */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bmr.h"
#include "model.h"

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s DT_S < reference\n", argv[0]);
        return 2;
    }
    double dt = strtod(argv[1], NULL);
    size_t n = 0;
    if (scanf("%zu", &n) != 1 || n == 0) {
        fprintf(stderr, "expected the sample count first\n");
        return 2;
    }
    double *ref = malloc(n * sizeof *ref), *theta = malloc(n * sizeof *theta), *cur = malloc(n * sizeof *cur);
    if (!ref || !theta || !cur) return 2;
    for (size_t i = 0; i < n; i++) {
        if (scanf("%la %la", &ref[i], &theta[i]) != 2) {
            fprintf(stderr, "sample %zu unreadable\n", i);
            return 2;
        }
    }
    static BmrCompensator c; /* large: not on the stack */
    int rc = bmr_compensator_init(&c, &bmr_model, dt);
    if (rc != BMR_OK) {
        fprintf(stderr, "bmr_compensator_init failed: %d\n", rc);
        return 1;
    }
    bmr_compensator_run(&c, ref, theta, n, cur);
    /* A second pass sample by sample after a reset gives the same commands. */
    bmr_compensator_reset(&c);
    size_t ahead = bmr_compensator_preview_samples(&c);
    for (size_t i = 0; i < n; i++) {
        BmrCommand cmd;
        if (ahead == 0) {
            bmr_compensator_step(&c, ref[i], theta[i], &cmd);
        } else {
            size_t j = i + ahead < n ? i + ahead : n - 1;
            if (i + ahead < n) {
                bmr_compensator_step_ahead(&c, ref[j], theta[j], &cmd);
            } else {
                continue; /* past the end run() extrapolates the angle; compared through run() only */
            }
        }
        if (memcmp(&cmd.current_a, &cur[i], sizeof(double)) != 0) {
            fprintf(stderr, "step and run differ at sample %zu\n", i);
            return 1;
        }
        if (cmd.coil1_a != 0.0 && cmd.coil2_a != 0.0) {
            fprintf(stderr, "both coils at sample %zu\n", i);
            return 1;
        }
    }
    for (size_t i = 0; i < n; i++) printf("%a\n", cur[i]);
    free(ref);
    free(theta);
    free(cur);
    return 0;
}
