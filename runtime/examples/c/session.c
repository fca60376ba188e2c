/* A C application embedding the VES runtime: load a basis, grab the free end of the
 * cantilever, pull it down 5 mm, read the force and the deformed part.
 * Build: cc session.c -I runtime/include -L target/release -lves_runtime -o session
 * Run:   ./session BASIS.h5 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "ves.h"

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s BASIS.h5\n", argv[0]);
        return 2;
    }
    VesBasis *basis = NULL;
    if (ves_basis_load(argv[1], 0, &basis) != VesStatus_Ok) {
        fprintf(stderr, "error: %s\n", ves_last_error());
        return 1;
    }
    uint32_t vertices = 0, modes = 0;
    uint64_t bytes = 0;
    ves_basis_info(basis, &vertices, &modes, &bytes);

    VesHaptics *sim = NULL;
    if (ves_haptics_new(basis, 1e-3, 2e4, 50.0, 1000.0, 1, 0, &sim) != VesStatus_Ok) {
        fprintf(stderr, "error: %s\n", ves_last_error());
        return 1;
    }
    ves_basis_free(basis); /* the simulation keeps its own reference */
    VesView *view = NULL;
    ves_view_new(sim, &view);

    VesHandInput in = {{1.0, 0.05, 0.05}, {0.0, 0.0, 0.0}, 1};
    VesHandOutput out;
    memset(&out, 0, sizeof out);
    for (int k = 0; k < 3000; k++) {
        double s = k < 500 ? k / 500.0 : 1.0;
        in.position[2] = 0.05 - 0.005 * s;
        if (ves_haptics_step(sim, &in, &out, 1) != VesStatus_Ok) {
            fprintf(stderr, "error: %s\n", ves_last_error());
            return 1;
        }
    }
    float *pos = malloc(sizeof(float) * 3 * vertices);
    if (ves_view_positions(view, pos, 3 * (size_t)vertices) != VesStatus_Ok) {
        fprintf(stderr, "error: %s\n", ves_last_error());
        return 1;
    }
    float lowest = pos[2];
    for (uint32_t i = 0; i < vertices; i++)
        if (pos[3 * i + 2] < lowest) lowest = pos[3 * i + 2];

    /* Bad input is a status and a message, never a crash. */
    VesBasis *missing = NULL;
    VesStatus st = ves_basis_load("/nonexistent/basis.h5", 0, &missing);
    int error_ok = st == VesStatus_Load && strlen(ves_last_error()) > 0 && missing == NULL;
    int null_ok = ves_haptics_step(NULL, &in, &out, 1) == VesStatus_NullArgument;

    printf("vertices %u modes %u bytes %llu force %.9e %.9e %.9e vertex %u lowest_z %.9e errors_ok %d\n",
           vertices, modes, (unsigned long long)bytes, out.force[0], out.force[1], out.force[2], out.vertex,
           (double)lowest, error_ok && null_ok);
    free(pos);
    ves_view_free(view);
    ves_haptics_free(sim);
    return 0;
}
