/*
 * A C program using the runtime through adwi.h alone, run by tests/c_abi.rs.
 *
 * Usage: smoke TABLE MISSING CORRUPT HYBRID < targets
 *   TABLE    a valid table file
 *   MISSING  a path that does not exist
 *   CORRUPT  a file holding a damaged table
 *   HYBRID   a hybrid table of a six-joint robot
 * Each line of standard input is "x y z config"; for each, the program queries and
 * compensates through a mapped handle and a handle opened from bytes, and prints the
 * answers with 17 significant digits. Then a line "hybrid", and lines "x y z j1 ... j6"
 * (joints in radians), each queried of HYBRID with its joints. Every other line it
 * prints is "name value ...",
 * for the Rust test to compare with what it expects.
 */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "adwi.h"

/* The layout and values the header declares, as the library has them: the Rust side
 * asserts the same numbers (runtime/src/capi.rs, layout_and_values_match_the_c_header), so
 * a change on either side alone fails to compile here or fails that test. */
_Static_assert(sizeof(adwi_result) == 4, "adwi_result is an int");
_Static_assert(sizeof(adwi_correction) == 64, "sizeof adwi_correction");
_Static_assert(_Alignof(adwi_correction) == 8, "alignof adwi_correction");
_Static_assert(offsetof(adwi_correction, position_error_mm) == 0, "position_error_mm");
_Static_assert(offsetof(adwi_correction, orientation_error_rad) == 24, "orientation_error_rad");
_Static_assert(offsetof(adwi_correction, neighbours) == 48, "neighbours");
_Static_assert(offsetof(adwi_correction, status) == 52, "status");
_Static_assert(offsetof(adwi_correction, residual) == 56, "residual");
_Static_assert(offsetof(adwi_correction, evidence) == 60, "evidence");
_Static_assert(sizeof(adwi_compensation) == 128, "sizeof adwi_compensation");
_Static_assert(_Alignof(adwi_compensation) == 8, "alignof adwi_compensation");
_Static_assert(offsetof(adwi_compensation, command_position_mm) == 0, "command_position_mm");
_Static_assert(offsetof(adwi_compensation, command_rotation_rad) == 24, "command_rotation_rad");
_Static_assert(offsetof(adwi_compensation, correction) == 48, "correction");
_Static_assert(offsetof(adwi_compensation, iterations) == 112, "iterations");
_Static_assert(offsetof(adwi_compensation, converged) == 116, "converged");
_Static_assert(offsetof(adwi_compensation, residual_mm) == 120, "residual_mm");
_Static_assert(ADWI_OK == 0 && ADWI_NULL_POINTER == 1 && ADWI_INVALID_ARGUMENT == 2 &&
                   ADWI_IO == 3 && ADWI_INVALID_TABLE == 4 && ADWI_UNSUPPORTED_VERSION == 5 &&
                   ADWI_LOCK == 6 && ADWI_PANIC == 7 && ADWI_INVALID_HANDLE == 8 &&
                   ADWI_OUT_OF_MEMORY == 9,
               "adwi_result values");
_Static_assert(ADWI_STATUS_OK == 0 && ADWI_STATUS_OUTSIDE_GRID == 1 &&
                   ADWI_STATUS_NO_NEIGHBOUR == 2 && ADWI_STATUS_INVALID_INPUT == 3 &&
                   ADWI_STATUS_MISSING_JOINTS == 4 && ADWI_STATUS_NUMERICAL_FAILURE == 5 &&
                   ADWI_STATUS_UNCOVERED_CELL == 6 && ADWI_STATUS_JOINTS_MISMATCH == 7,
               "ADWI_STATUS_* values");
_Static_assert(ADWI_RESIDUAL_FULL == 0 && ADWI_RESIDUAL_FADED == 1 && ADWI_RESIDUAL_MODEL_ONLY == 2,
               "ADWI_RESIDUAL_* values");
_Static_assert(ADWI_OPEN_PREFAULT == 1u && ADWI_OPEN_LOCK == 2u && ADWI_OPEN_LOCK_REQUIRED == 4u,
               "ADWI_OPEN_* values");

static unsigned char *read_file(const char *path, size_t *len) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *buf = malloc(n > 0 ? (size_t)n : 1);
    if (buf && fread(buf, 1, (size_t)n, f) != (size_t)n) {
        free(buf);
        buf = NULL;
    }
    fclose(f);
    *len = (size_t)n;
    return buf;
}

static void print_open_error(const char *name, adwi_result code) {
    char message[512];
    size_t full = adwi_last_open_error(message, sizeof message);
    printf("%s %d %zu %s | %s\n", name, (int)code, full, adwi_result_name(code), message);
}

int main(int argc, char **argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: smoke TABLE MISSING CORRUPT HYBRID < targets\n");
        return 2;
    }
    adwi_table *table = NULL;
    adwi_table *untouched = (adwi_table *)&table; /* a sentinel no open may overwrite */
    adwi_table *probe = untouched;

    /* Refusals: codes, messages, outputs left alone. */
    print_open_error("open_null_path", adwi_table_open(NULL, &probe));
    printf("open_null_out %d\n", (int)adwi_table_open(argv[1], NULL));
    print_open_error("open_missing", adwi_table_open(argv[2], &probe));
    size_t corrupt_len = 0;
    unsigned char *corrupt = read_file(argv[3], &corrupt_len);
    if (!corrupt) {
        fprintf(stderr, "cannot read %s\n", argv[3]);
        return 2;
    }
    print_open_error("open_corrupt_bytes", adwi_table_open_bytes(corrupt, corrupt_len, &probe));
    print_open_error("open_corrupt_file", adwi_table_open(argv[3], &probe));
    printf("open_null_bytes %d\n", (int)adwi_table_open_bytes(NULL, 10, &probe));
    free(corrupt);
    printf("handle_untouched %d\n", probe == untouched);

    /* Two handles on the same table: mapped (prefaulted, locked if allowed) and copied. */
    adwi_result code = adwi_table_open_with(argv[1], ADWI_OPEN_PREFAULT | ADWI_OPEN_LOCK, &table);
    print_open_error("open", code);
    if (code != ADWI_OK) return 1;
    size_t len = 0;
    unsigned char *bytes = read_file(argv[1], &len);
    adwi_table *copy = NULL;
    code = adwi_table_open_bytes(bytes, len, &copy);
    free(bytes); /* the handle holds its own aligned copy */
    printf("open_bytes %d\n", (int)code);
    if (code != ADWI_OK) return 1;
    uint32_t samples = 0;
    code = adwi_table_sample_count(table, &samples);
    printf("sample_count %d %u\n", (int)code, samples);

    /* Query refusals. */
    const double target[3] = {0.0, 0.0, 0.0};
    adwi_correction c;
    memset(&c, 0xAB, sizeof c);
    adwi_correction sentinel = c;
    printf("query_null_table %d\n", (int)adwi_table_query(NULL, target, -1, &c));
    printf("query_null_target %d\n", (int)adwi_table_query(table, NULL, -1, &c));
    printf("query_null_out %d\n", (int)adwi_table_query(table, target, -1, NULL));
    printf("query_bad_config %d\n", (int)adwi_table_query(table, target, 300, &c));
    printf("query_untouched %d\n", memcmp(&c, &sentinel, sizeof c) == 0);
    const double joints[6] = {0.0, -1.0, 1.5, 0.0, 0.5, 0.0};
    printf("query_joints_null_joints %d\n",
           (int)adwi_table_query_joints(table, target, -1, NULL, 6, &c));
    printf("query_joints_too_many %d\n",
           (int)adwi_table_query_joints(table, target, -1, joints, 100, &c));
    uint32_t joint_count = 99;
    code = adwi_table_joint_count(table, &joint_count);
    printf("joint_count %d %u\n", (int)code, joint_count);
    adwi_compensation k;
    memset(&k, 0xCD, sizeof k);
    printf("compensate_null_out %d\n",
           (int)adwi_table_compensate(table, target, -1, 1e-6, 20, NULL));
    printf("compensate_bad_tolerance %d\n",
           (int)adwi_table_compensate(table, target, -1, -1.0, 20, &k));

    /* Handles no open function returned: readable memory without the open marker (zeros,
     * garbage) and a misaligned pointer. Refused with ADWI_INVALID_HANDLE, outputs and
     * memory untouched. (A closed handle is refused the same way in the common case, but
     * using one is undefined behaviour, so it is not exercised here.) */
    static uint64_t zeroed[64];
    uint64_t garbage[64];
    memset(garbage, 0xAB, sizeof garbage);
    adwi_table *bogus[3] = {(adwi_table *)zeroed, (adwi_table *)garbage,
                            (adwi_table *)((unsigned char *)zeroed + 1)};
    for (int i = 0; i < 3; i++) {
        uint32_t n = 12345;
        adwi_compensation before_k = k;
        printf("invalid_handle %d %d %d %d %d\n",
               (int)adwi_table_query(bogus[i], target, -1, &c),
               (int)adwi_table_query_joints(bogus[i], target, -1, joints, 6, &c),
               (int)adwi_table_compensate(bogus[i], target, -1, 1e-6, 20, &k),
               (int)adwi_table_sample_count(bogus[i], &n),
               (int)adwi_table_close(bogus[i]));
        printf("invalid_handle_untouched %d\n",
               memcmp(&c, &sentinel, sizeof c) == 0 && n == 12345 &&
                   memcmp(&k, &before_k, sizeof k) == 0);
    }
    int zeroed_untouched = 1;
    for (int i = 0; i < 64; i++) zeroed_untouched &= zeroed[i] == 0;
    printf("invalid_handle_memory_untouched %d\n", zeroed_untouched);
    printf("result_name_8 %s\n", adwi_result_name(ADWI_INVALID_HANDLE));

    /* Answers. */
    double x, y, z;
    int config;
    while (scanf("%lf %lf %lf %d", &x, &y, &z, &config) == 4) {
        const double p[3] = {x, y, z};
        adwi_correction a, b, e;
        /* Different garbage in each: the comparisons below hold only if every byte is
         * written. */
        memset(&a, 0x11, sizeof a);
        memset(&b, 0x22, sizeof b);
        memset(&e, 0x33, sizeof e);
        memset(&c, 0x44, sizeof c);
        if (adwi_table_query(table, p, config, &a) != ADWI_OK ||
            adwi_table_query(copy, p, config, &b) != ADWI_OK ||
            adwi_table_query_exact(table, p, config, &e) != ADWI_OK) {
            printf("query_failed\n");
            return 1;
        }
        printf("query %d %u %d %.17g %.17g %.17g %.17g %.17g %.17g\n", a.status, a.neighbours,
               a.residual, a.position_error_mm[0], a.position_error_mm[1], a.position_error_mm[2],
               a.orientation_error_rad[0], a.orientation_error_rad[1],
               a.orientation_error_rad[2]);
        printf("exact %d %u %.17g %.17g %.17g\n", e.status, e.neighbours,
               e.position_error_mm[0], e.position_error_mm[1], e.position_error_mm[2]);
        printf("handles_agree %d\n", memcmp(&a, &b, sizeof a) == 0);
        /* A position-only table without a joint screen ignores the joint angles. */
        if (adwi_table_query_joints(table, p, config, joints, 6, &b) != ADWI_OK ||
            adwi_table_query_joints_exact(table, p, config, joints, 6, &c) != ADWI_OK) {
            printf("query_failed\n");
            return 1;
        }
        printf("query_joints_agree %d %d\n", memcmp(&a, &b, sizeof a) == 0,
               memcmp(&e, &c, sizeof e) == 0);
        /* A target that is not a point has no command: refused, never ADWI_OK with NaN. */
        if (!(isfinite(x) && isfinite(y) && isfinite(z))) {
            adwi_compensation before = k;
            printf("compensate_refused %d %d %d\n",
                   (int)adwi_table_compensate(table, p, config, 1e-9, 50, &k),
                   (int)adwi_table_compensate_exact(table, p, config, 1e-9, 50, &k),
                   memcmp(&k, &before, sizeof k) == 0);
            continue;
        }
        if (adwi_table_compensate(table, p, config, 1e-9, 50, &k) != ADWI_OK) {
            printf("compensate_failed\n");
            return 1;
        }
        printf("compensate %d %u %d %.17g %.17g %.17g %.17g\n", k.correction.status,
               k.iterations, k.converged, k.command_position_mm[0], k.command_position_mm[1],
               k.command_position_mm[2], k.residual_mm);
        if (adwi_table_compensate_exact(table, p, config, 1e-9, 50, &k) != ADWI_OK) {
            printf("compensate_failed\n");
            return 1;
        }
        printf("compensate_exact %d %u %d %.17g %.17g %.17g %.17g\n", k.correction.status,
               k.iterations, k.converged, k.command_position_mm[0], k.command_position_mm[1],
               k.command_position_mm[2], k.residual_mm);
    }
    printf("close %d %d %d\n", (int)adwi_table_close(copy), (int)adwi_table_close(table),
           (int)adwi_table_close(NULL));

    /* A hybrid table: the model everywhere, the residual where the samples are. */
    char word[16];
    adwi_table *hybrid = NULL;
    if (scanf("%15s", word) != 1 || strcmp(word, "hybrid") != 0 ||
        adwi_table_open(argv[4], &hybrid) != ADWI_OK) {
        printf("hybrid_failed\n");
        return 1;
    }
    double q[6];
    while (scanf("%lf %lf %lf %lf %lf %lf %lf %lf %lf", &x, &y, &z, &q[0], &q[1], &q[2], &q[3],
                 &q[4], &q[5]) == 9) {
        const double p[3] = {x, y, z};
        adwi_correction h;
        if (adwi_table_query_joints(hybrid, p, -1, q, 6, &h) != ADWI_OK) {
            printf("query_failed\n");
            return 1;
        }
        printf("hybrid %d %u %d %.17g %.17g %.17g\n", h.status, h.neighbours, h.residual,
               h.position_error_mm[0], h.position_error_mm[1], h.position_error_mm[2]);
        /* The same target for a 200 mm TCP, the tool pointing down the base's z axis. */
        const double tcp[3] = {0.0, 0.0, 200.0};
        const double down[3] = {3.141592653589793, 0.0, 0.0};
        adwi_correction t;
        if (adwi_table_query_pose(hybrid, p, down, tcp, -1, q, 6, &t) != ADWI_OK ||
            adwi_table_query_pose(hybrid, p, NULL, NULL, -1, NULL, 6, &h) != ADWI_NULL_POINTER) {
            printf("pose_failed\n");
            return 1;
        }
        printf("pose %d %d %u %.17g %.17g %.17g %.17g %.17g %.17g\n", t.status, t.residual,
               t.evidence, t.position_error_mm[0], t.position_error_mm[1],
               t.position_error_mm[2], t.orientation_error_rad[0], t.orientation_error_rad[1],
               t.orientation_error_rad[2]);
    }
    printf("hybrid_close %d\n", (int)adwi_table_close(hybrid));
    printf("done\n");
    return 0;
}
