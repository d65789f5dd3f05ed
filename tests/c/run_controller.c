/* Runs the closed-loop controller around an exported model's compensator on a reference, angle and measured
 * torque read from stdin and prints the commanded currents, one per line, as exact hexadecimal doubles. Usage:
 * run_controller DT_S < "n\n ref theta measured\n ..." (compiled with the header `bmr export MODEL --c model.h`
 * wrote, `include/bmr.h` and the bmr static library). A measured value of nan is a missing measurement. */
#include <stdio.h>
#include <stdlib.h>

#include "bmr.h"
#include "model.h"

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s DT_S < samples\n", argv[0]);
        return 2;
    }
    double dt = strtod(argv[1], NULL);
    size_t n = 0;
    if (scanf("%zu", &n) != 1 || n == 0) {
        fprintf(stderr, "expected the sample count first\n");
        return 2;
    }
    static BmrController c; /* large: not on the stack */
    BmrControllerSettings settings = bmr_controller_default_settings();
    int rc = bmr_controller_init(&c, &bmr_model, dt, &settings);
    if (rc != BMR_OK) {
        fprintf(stderr, "bmr_controller_init failed: %d\n", rc);
        return 1;
    }
    for (size_t i = 0; i < n; i++) {
        double r, theta, measured;
        if (scanf("%la %la %la", &r, &theta, &measured) != 3) {
            fprintf(stderr, "sample %zu unreadable\n", i);
            return 2;
        }
        BmrCommand cmd;
        bmr_controller_step(&c, r, theta, measured, &cmd);
        if (cmd.coil1_a != 0.0 && cmd.coil2_a != 0.0) {
            fprintf(stderr, "both coils at sample %zu\n", i);
            return 1;
        }
        printf("%a\n", cmd.current_a);
    }
    double gain = 0.0;
    bmr_controller_estimates(&c, &gain, NULL, NULL);
    fprintf(stderr, "gain %a\n", gain);
    return 0;
}
