/*
 * A C program using the runtime through adwi.h alone, run by tests/c_abi.rs.
 *
 * Usage: smoke TABLE MISSING CORRUPT < targets
 *   TABLE    a valid table file
 *   MISSING  a path that does not exist
 *   CORRUPT  a file holding a damaged table
 * Each line of standard input is "x y z config"; for each, the program queries and
 * compensates through a mapped handle and a handle opened from bytes, and prints the
 * answers with 17 significant digits. Every other line it prints is "name value ...",
 * for the Rust test to compare with what it expects.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "adwi.h"

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
    if (argc != 4) {
        fprintf(stderr, "usage: smoke TABLE MISSING CORRUPT < targets\n");
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
           (int)adwi_table_query_joints(table, target, -1, NULL, &c));
    adwi_compensation k;
    printf("compensate_null_out %d\n",
           (int)adwi_table_compensate(table, target, -1, 1e-6, 20, NULL));
    printf("compensate_bad_tolerance %d\n",
           (int)adwi_table_compensate(table, target, -1, -1.0, 20, &k));

    /* Answers. */
    double x, y, z;
    int config;
    while (scanf("%lf %lf %lf %d", &x, &y, &z, &config) == 4) {
        const double p[3] = {x, y, z};
        adwi_correction a, b;
        if (adwi_table_query(table, p, config, &a) != ADWI_OK ||
            adwi_table_query(copy, p, config, &b) != ADWI_OK) {
            printf("query_failed\n");
            return 1;
        }
        printf("query %d %u %.17g %.17g %.17g %.17g %.17g %.17g\n", a.status, a.neighbours,
               a.position_error_mm[0], a.position_error_mm[1], a.position_error_mm[2],
               a.orientation_error_rad[0], a.orientation_error_rad[1],
               a.orientation_error_rad[2]);
        printf("handles_agree %d\n", memcmp(&a, &b, sizeof a) == 0);
        /* A position-only table without a joint screen ignores the joint angles. */
        if (adwi_table_query_joints(table, p, config, joints, &b) != ADWI_OK) {
            printf("query_failed\n");
            return 1;
        }
        printf("query_joints_agree %d\n", memcmp(&a, &b, sizeof a) == 0);
        if (adwi_table_compensate(table, p, config, 1e-9, 50, &k) != ADWI_OK) {
            printf("compensate_failed\n");
            return 1;
        }
        printf("compensate %d %u %d %.17g %.17g %.17g %.17g\n", k.correction.status,
               k.iterations, k.converged, k.command_position_mm[0], k.command_position_mm[1],
               k.command_position_mm[2], k.residual_mm);
    }
    adwi_table_close(copy);
    adwi_table_close(table);
    adwi_table_close(NULL);
    printf("done\n");
    return 0;
}
