/*
 * adwi.h — C interface to the adwi runtime: open a compiled robot error-correction table
 * and query it from a controller. Units: millimetres and radians, robot base frame.
 *
 * Build the libraries with `cargo build --release -p adwi-runtime`; both land in
 * target/release. Link on Linux either
 *  - statically, naming the archive by its path (with -ladwi_runtime the linker would take
 *    the .so beside it, and the program would not find it at run time), followed by the
 *    system libraries Rust's standard library needs
 *    (`rustc --print native-static-libs`):
 *        cc app.c -I runtime/include target/release/libadwi_runtime.a \
 *           -lgcc_s -lutil -lrt -lpthread -lm -ldl -lc
 *  - or dynamically, telling the loader where the library is (or installing it where the
 *    loader looks, and running ldconfig):
 *        cc app.c -I runtime/include -L "$PWD/target/release" -ladwi_runtime \
 *           -Wl,-rpath,"$PWD/target/release"
 *
 * Conventions:
 *  - Every function returns an adwi_result. Outputs are written only on ADWI_OK; a failed
 *    call leaves them untouched.
 *  - Null pointers are refused with ADWI_NULL_POINTER; a handle that is not open, in the
 *    common case, with ADWI_INVALID_HANDLE (see adwi_table).
 *  - A panic inside the library never unwinds into C: it becomes ADWI_PANIC.
 *  - The query and compensate functions do not allocate, lock or block, and may be called
 *    from several threads on the same handle at once. A handle must not be closed while
 *    another thread uses it.
 *  - Two tiers answer: adwi_table_query, _query_joints and _compensate serve the
 *    continuous correction field (a servo loop's input: no jumps); the _exact variants
 *    answer by the paper's method to the digit. A table without a served field (format
 *    version 1, or built with a joint-space screen) answers both from the exact tier.
 *  - Only the open functions record a detailed message, per thread; read it with
 *    adwi_last_open_error.
 *
 * Example:
 *
 *     adwi_table *t = NULL;
 *     if (adwi_table_open("kr150.tbl", &t) != ADWI_OK) {
 *         char msg[512];
 *         adwi_last_open_error(msg, sizeof msg);
 *         fprintf(stderr, "%s\n", msg);
 *         return 1;
 *     }
 *     const double target[3] = {2000.0, 700.0, 1000.0};
 *     adwi_correction c;
 *     if (adwi_table_query(t, target, -1, &c) == ADWI_OK && c.status == ADWI_STATUS_OK) {
 *         // command target - c.position_error_mm
 *     }
 *     adwi_table_close(t);
 */
#ifndef ADWI_H
#define ADWI_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* An open, validated table. Opaque.
 *
 * Every function taking a handle first reads a marker the library keeps at its start and
 * answers ADWI_INVALID_HANDLE, touching nothing else, when it is not that of an open table.
 * This catches the common mistakes of querying a handle after adwi_table_close or closing
 * it twice, shortly after the close. It is a check, not a guarantee, and these remain
 * undefined behaviour: using a closed handle (its memory may have been returned to the
 * system since, or reused for a newly opened handle, which the stale pointer then reaches),
 * closing a handle while another thread uses it, and passing a pointer that no open
 * function returned (readable memory without the marker is refused, but any other pointer
 * may crash). */
typedef struct adwi_table adwi_table;

/* Result codes. */
typedef enum adwi_result {
    ADWI_OK = 0,                  /* success; outputs written */
    ADWI_NULL_POINTER = 1,        /* a required pointer was null */
    ADWI_INVALID_ARGUMENT = 2,    /* config outside -1..254, tolerance negative or NaN,
                                     max_iterations 0, a compensation target not finite,
                                     unknown open flags, path not UTF-8 */
    ADWI_IO = 3,                  /* the file cannot be read or mapped */
    ADWI_INVALID_TABLE = 4,       /* truncated, corrupt, wrong magic, bad checksum */
    ADWI_UNSUPPORTED_VERSION = 5, /* a format version this runtime does not read */
    ADWI_LOCK = 6,                /* ADWI_OPEN_LOCK_REQUIRED and mlock failed */
    ADWI_PANIC = 7,               /* a bug caught at the boundary */
    ADWI_INVALID_HANDLE = 8,      /* not an open handle: closed already, or never opened
                                     (see adwi_table) */
    ADWI_OUT_OF_MEMORY = 9        /* adwi_table_open_bytes could not allocate its copy (the
                                     process is never aborted) */
} adwi_result;

/* What a query's answer means (adwi_correction.status). */
enum {
    ADWI_STATUS_OK = 0,             /* predicted from at least one admissible neighbour */
    ADWI_STATUS_OUTSIDE_GRID = 1,   /* target outside the table's grid; correction zero */
    ADWI_STATUS_NO_NEIGHBOUR = 2,   /* no admissible sample; correction zero */
    ADWI_STATUS_INVALID_INPUT = 3,  /* target not finite; correction zero */
    ADWI_STATUS_MISSING_JOINTS = 4, /* hybrid table queried without joint angles: use
                                       adwi_table_query_joints; correction zero */
    ADWI_STATUS_NUMERICAL_FAILURE = 5, /* the prediction came out NaN or infinite (degenerate
                                          geometry, e.g. a target and a sample both within
                                          ~1e-160 mm of the base origin) and is withheld;
                                          correction zero */
    ADWI_STATUS_UNCOVERED_CELL = 6, /* the served field is not defined in the target's cell
                                       (a corner has no admissible sample; never
                                       extrapolated; position-only tables); the exact tier
                                       may answer there; correction zero */
    ADWI_STATUS_JOINTS_MISMATCH = 7 /* hybrid table: the joint values' nominal forward
                                       kinematics puts the tool farther from the target than
                                       the table allows (joints_rad takes radians: degrees
                                       given?); correction zero */
};

/* How much of a hybrid table's residual field a correction holds
 * (adwi_correction.residual; meaningful when status is ADWI_STATUS_OK). The calibrated
 * model answers everywhere; the residual where the samples are, fading to zero across
 * the last cell and within a fade length of the grid box (docs/runtime.md, "The
 * residual flag"). */
enum {
    ADWI_RESIDUAL_FULL = 0,      /* all of it (every position-only table's answer) */
    ADWI_RESIDUAL_FADED = 1,     /* part of it: a cell corner without a value, outside
                                    the grid within the fade length, or (version 6) a
                                    joint within 3 degrees beyond the samples' angles */
    ADWI_RESIDUAL_MODEL_ONLY = 2 /* none: the calibrated model alone */
};

/* Flags for adwi_table_open_with. */
#define ADWI_OPEN_PREFAULT 1u      /* fault every page in at open */
#define ADWI_OPEN_LOCK 2u          /* mlock the table, best effort */
#define ADWI_OPEN_LOCK_REQUIRED 4u /* mlock the table or fail with ADWI_LOCK */

/* The predicted error at a target: command target - position_error_mm to land on it. */
typedef struct adwi_correction {
    double position_error_mm[3];     /* actual - nominal, mm */
    double orientation_error_rad[3]; /* rotation vector of R_actual * R_nominal^T, rad; 0 when the samples measured none */
    uint32_t neighbours;             /* neighbours weighted (exact), nodes blended (served: 8) */
    int32_t status;                  /* ADWI_STATUS_*; other fields are zero unless OK */
    int32_t residual;                /* ADWI_RESIDUAL_*: how much of a hybrid table's
                                        residual field the correction holds */
    uint32_t evidence;               /* ADWI_EVIDENCE_* bits: where the answer lies beyond
                                        the samples (0 within; the struct has no padding:
                                        memcmp compares) */
} adwi_correction;

/* adwi_correction.evidence bits: where an answer lies beyond what the table's samples
 * cover (docs/runtime.md, "Evidence"). A hybrid table's model still answers there. */
#define ADWI_EVIDENCE_WITHIN 0u      /* within the samples' evidence */
#define ADWI_EVIDENCE_ORIENTATION 1u /* an approach axis the samples never had */
#define ADWI_EVIDENCE_TCP 2u         /* a TCP the table cannot relate to its point
                                        by its samples (docs/runtime.md) */
#define ADWI_EVIDENCE_JOINTS 4u      /* a joint beyond the angles its model terms were
                                        identified over */

/* The command that lands the robot on a target: command + error(command) = target. */
typedef struct adwi_compensation {
    double command_position_mm[3];  /* position to command, mm */
    double command_rotation_rad[3]; /* R_cmd = Exp(command_rotation_rad) * R_target */
    adwi_correction correction;     /* the correction predicted at the command */
    uint32_t iterations;            /* queries made */
    int32_t converged;              /* 1 if the tolerance was reached */
    double residual_mm;             /* |command + error(command) - target|, mm */
} adwi_compensation;

/* Opens the table file at path (UTF-8) by memory map and validates it. The file must not be
 * modified while open: replace tables by renaming a new file into place. */
adwi_result adwi_table_open(const char *path, adwi_table **out);

/* As adwi_table_open, with ADWI_OPEN_* flags; any other bit is ADWI_INVALID_ARGUMENT. A
 * path that is not a regular file (a FIFO, a device) is ADWI_IO at once, never waited on. */
adwi_result adwi_table_open_with(const char *path, uint32_t flags, adwi_table **out);

/* Copies len bytes into aligned memory and validates them as a table; the caller's buffer
 * may be freed afterwards. */
adwi_result adwi_table_open_bytes(const uint8_t *bytes, size_t len, adwi_table **out);

/* The served correction (the continuous field) at target_mm for configuration config
 * (-1 = unknown). ADWI_OK whenever the table answered; out->status says whether the
 * correction holds. */
adwi_result adwi_table_query(const adwi_table *table, const double target_mm[3],
                             int32_t config, adwi_correction *out);

/* As adwi_table_query, from the exact tier: the paper's method to the digit. */
adwi_result adwi_table_query_exact(const adwi_table *table, const double target_mm[3],
                                   int32_t config, adwi_correction *out);

/* As adwi_table_query, for a target the controller reaches with the n_joints joint values
 * joints_rad (rad; mm for prismatic joints). n_joints must be the table's joint count
 * (adwi_table_joint_count) when it has one, else ADWI_INVALID_ARGUMENT. The only query a
 * hybrid table (calibrated kinematic model plus the residual field) answers; on any table
 * it also applies the joint-space screen when the table was built with one. */
adwi_result adwi_table_query_joints(const adwi_table *table, const double target_mm[3],
                                    int32_t config, const double *joints_rad,
                                    size_t n_joints, adwi_correction *out);

/* As adwi_table_query_joints, from the exact tier. */
adwi_result adwi_table_query_joints_exact(const adwi_table *table, const double target_mm[3],
                                          int32_t config, const double *joints_rad,
                                          size_t n_joints, adwi_correction *out);

/* The served correction at a pose: target_mm is the position of the TCP at tcp_mm (mm,
 * flange frame; NULL: the table's measured point) with the tool's orientation
 * rotation_rad (rotation vector, rad, base frame; NULL: not known), reached with the
 * n_joints values at joints_rad (NULL and 0 for a position-only table). A hybrid table
 * answers the error at the TCP (its answer's rotation, the model's and the residual's,
 * turns the lever from its point where its samples measured orientation; else the lever
 * is unturned, and flagged); out->evidence says where the answer lies beyond the
 * samples. */
adwi_result adwi_table_query_pose(const adwi_table *table, const double target_mm[3],
                                  const double *rotation_rad, const double *tcp_mm,
                                  int32_t config, const double *joints_rad, size_t n_joints,
                                  adwi_correction *out);

/* Iterates command <- target - error(command) on the served field until the residual is at
 * most tolerance_mm or max_iterations queries were made (at least 1: 0 is
 * ADWI_INVALID_ARGUMENT, as is a target that is not finite). On ADWI_OK the command is
 * finite. */
adwi_result adwi_table_compensate(const adwi_table *table, const double target_mm[3],
                                  int32_t config, double tolerance_mm,
                                  uint32_t max_iterations, adwi_compensation *out);

/* As adwi_table_compensate, on the exact field (which can jump: the iteration may then
 * cycle and report converged = 0). */
adwi_result adwi_table_compensate_exact(const adwi_table *table, const double target_mm[3],
                                        int32_t config, double tolerance_mm,
                                        uint32_t max_iterations, adwi_compensation *out);

/* The number of joint values adwi_table_query_joints takes: the robot's joint count, or 0
 * for a table whose answers do not depend on joint values. */
adwi_result adwi_table_joint_count(const adwi_table *table, uint32_t *out);

/* The number of samples in the table. */
adwi_result adwi_table_sample_count(const adwi_table *table, uint32_t *out);

/* Closes a handle, unmapping or freeing its table; null is ignored (ADWI_OK). A handle
 * without the marker of an open one (closed already, say) is refused with
 * ADWI_INVALID_HANDLE and nothing is freed (see adwi_table for what remains undefined). */
adwi_result adwi_table_close(adwi_table *table);

/* A static name for a result code; never null. */
const char *adwi_result_name(int code);

/* Copies this thread's last open error message into buf (at most len bytes including the
 * NUL, truncated if needed; nothing is written if len is 0) and returns the full message
 * length without the NUL. Empty after a successful open. */
size_t adwi_last_open_error(char *buf, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* ADWI_H */
