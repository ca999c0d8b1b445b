// AprilTag's pose code (libapriltag, Debian libapriltag-dev) on the corner dataset written by
// `cargo run --release --example corner_accuracy` (target/accuracy/corners.csv).
// Built and run by scripts/bench_apriltag_pose.sh.
//
//   pose_bench CORNERS.csv [POSES_OUT.csv [--no-timing]]
//                                            times both methods, prints
//                                            "<method> <median ns per call> <calls per round>",
//                                            and (with POSES_OUT) writes every pose first.
//   pose_bench --exact CORNERS.csv           round trip on exact corners projected from the true
//                                            poses: prints the largest rotation / position error.
//
// Methods:
//   apriltag_estimate_tag_pose   libapriltag's estimate_tag_pose(): homography pose, orthogonal
//                                iteration (50 iterations), Schweighofer & Pinz second minimum,
//                                orthogonal iteration again, lower object-space error wins.
//   apriltag_homography          the homography-only pose (apriltag's
//                                estimate_pose_for_tag_homography). The Debian build of
//                                libapriltag.so.3 exports only estimate_tag_pose (no
//                                estimate_pose_for_tag_homography, homography_to_pose, matd_*), so
//                                this is a re-implementation here of apriltag's homography_to_pose
//                                (called with -fx, as apriltag does, then the diag(1,-1,-1) fix and
//                                the polar decomposition of the rotation); see homography_pose().
//
// Both timings include building the detection's homography from the four corners (a 4-point
// DLT, as the detector does in quad_update_homographies), since we start from corners.
//
// Frames. AprilTag's tag frame: centred, x right, y down (as the tag is seen in the image),
// z = x * y into the tag; det->p[i] are the images of tag points (-1,1), (1,1), (1,-1), (-1,-1)
// (half-size units), i.e. BL, BR, TR, TL; det->H maps those tag points to pixels. Its camera frame
// is OpenCV's (x right, y down, z forward). Our marker frame (docs/conventions.md) has the same axes
// with the origin at TR, so R_ours = R_apriltag and the marker centre is t.
#define _POSIX_C_SOURCE 200809L
#include <apriltag/apriltag.h>
#include <apriltag/apriltag_pose.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct {
    double R[9], c[3];  // true rotation (ours) and marker centre, mm
    double q[8];        // corners, qr order TL, TR, BR, BL: u, v pairs
} Case;

static double hdr(const char* line, const char* key) {
    const char* p = strstr(line, key);
    if (!p) {
        fprintf(stderr, "header has no %s\n", key);
        exit(1);
    }
    return atof(p + strlen(key) + 1);
}

static double fx, fy, cx, cy, side;

static Case* read_cases(const char* path, size_t* n) {
    FILE* f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        exit(1);
    }
    char line[4096];
    if (!fgets(line, sizeof line, f)) exit(1);
    fx = fy = hdr(line, "f_px");
    cx = hdr(line, "cx_px");
    cy = hdr(line, "cy_px");
    side = hdr(line, "marker_mm");
    if (!fgets(line, sizeof line, f)) exit(1);  // column names
    size_t cap = 1024;
    Case* cases = malloc(cap * sizeof(Case));
    *n = 0;
    while (fgets(line, sizeof line, f)) {
        double v[21];
        int k = 0;
        char* s = line;
        while (k < 21) {
            char* end;
            v[k] = strtod(s, &end);
            if (end == s) break;
            k++;
            s = end;
            if (*s == ',') s++;
        }
        if (k != 21) continue;
        if (*n == cap) cases = realloc(cases, (cap *= 2) * sizeof(Case));
        Case* c = &cases[(*n)++];
        memcpy(c->R, v + 1, 9 * sizeof(double));
        memcpy(c->c, v + 10, 3 * sizeof(double));
        memcpy(c->q, v + 13, 8 * sizeof(double));
    }
    fclose(f);
    return cases;
}

// Homography mapping (x[i], y[i]) to (u[i], v[i]) exactly, h22 = 1 (8x8 Gaussian elimination with
// partial pivoting), written into the 3x3 matd_t H.
static int homography4(const double x[4], const double y[4], const double u[4], const double v[4],
                       matd_t* H) {
    double A[8][9];
    for (int i = 0; i < 4; i++) {
        double* r = A[2 * i];
        r[0] = x[i], r[1] = y[i], r[2] = 1, r[3] = r[4] = r[5] = 0;
        r[6] = -x[i] * u[i], r[7] = -y[i] * u[i], r[8] = u[i];
        r = A[2 * i + 1];
        r[0] = r[1] = r[2] = 0, r[3] = x[i], r[4] = y[i], r[5] = 1;
        r[6] = -x[i] * v[i], r[7] = -y[i] * v[i], r[8] = v[i];
    }
    for (int col = 0; col < 8; col++) {
        int piv = col;
        for (int r = col + 1; r < 8; r++)
            if (fabs(A[r][col]) > fabs(A[piv][col])) piv = r;
        if (fabs(A[piv][col]) < 1e-300) return 0;
        if (piv != col)
            for (int k = 0; k < 9; k++) {
                double t = A[col][k];
                A[col][k] = A[piv][k];
                A[piv][k] = t;
            }
        for (int r = col + 1; r < 8; r++) {
            double m = A[r][col] / A[col][col];
            for (int k = col; k < 9; k++) A[r][k] -= m * A[col][k];
        }
    }
    double h[9];
    h[8] = 1;
    for (int r = 7; r >= 0; r--) {
        double s = A[r][8];
        for (int k = r + 1; k < 8; k++) s -= A[r][k] * h[k];
        h[r] = s / A[r][r];
    }
    memcpy(H->data, h, sizeof h);
    return 1;
}

// Tag points of det->p[0..3], half-size units.
static const double TAG_X[4] = {-1, 1, 1, -1};
static const double TAG_Y[4] = {1, 1, -1, -1};

static matd_t* new_mat(int rows, int cols) {
    matd_t* m = calloc(1, sizeof(matd_t) + (size_t)rows * cols * sizeof(double));
    m->nrows = rows;
    m->ncols = cols;
    return m;
}

// Fills det (p, c, H) from corners in qr order TL, TR, BR, BL.
static int fill_detection(const double q[8], apriltag_detection_t* det) {
    // qr index of det->p[i]: BL, BR, TR, TL
    static const int from_qr[4] = {3, 2, 1, 0};
    double u[4], v[4];
    for (int i = 0; i < 4; i++) {
        u[i] = det->p[i][0] = q[2 * from_qr[i]];
        v[i] = det->p[i][1] = q[2 * from_qr[i] + 1];
    }
    if (!homography4(TAG_X, TAG_Y, u, v, det->H)) return 0;
    det->c[0] = MATD_EL(det->H, 0, 2) / MATD_EL(det->H, 2, 2);  // image of the tag centre
    det->c[1] = MATD_EL(det->H, 1, 2) / MATD_EL(det->H, 2, 2);
    return 1;
}

// ---- homography-only pose: apriltag's estimate_pose_for_tag_homography, re-implemented ----

// Nearest rotation to M (polar decomposition, R = U V^T of the SVD), via Jacobi on M^T M.
static void nearest_rotation(const double M[9], double R[9]) {
    double A[9], V[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int k = 0; k < 3; k++) s += M[3 * k + i] * M[3 * k + j];
            A[3 * i + j] = s;
        }
    for (int sweep = 0; sweep < 30; sweep++) {
        double off = fabs(A[1]) + fabs(A[2]) + fabs(A[5]);
        if (off <= 1e-15 * (fabs(A[0]) + fabs(A[4]) + fabs(A[8]))) break;
        for (int p = 0; p < 2; p++)
            for (int q = p + 1; q < 3; q++) {
                double apq = A[3 * p + q];
                if (fabs(apq) < 1e-300) continue;
                double theta = (A[3 * q + q] - A[3 * p + p]) / (2 * apq);
                double t = (theta >= 0 ? 1 : -1) / (fabs(theta) + sqrt(theta * theta + 1));
                double c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < 3; k++) {  // A = J^T A J
                    double akp = A[3 * k + p], akq = A[3 * k + q];
                    A[3 * k + p] = c * akp - s * akq;
                    A[3 * k + q] = s * akp + c * akq;
                }
                for (int k = 0; k < 3; k++) {
                    double apk = A[3 * p + k], aqk = A[3 * q + k];
                    A[3 * p + k] = c * apk - s * aqk;
                    A[3 * q + k] = s * apk + c * aqk;
                }
                for (int k = 0; k < 3; k++) {
                    double vkp = V[3 * k + p], vkq = V[3 * k + q];
                    V[3 * k + p] = c * vkp - s * vkq;
                    V[3 * k + q] = s * vkp + c * vkq;
                }
            }
    }
    // M = U S V^T  =>  U V^T = M V S^-1 V^T (M has full rank here: two unit-ish columns and their
    // cross product).
    double MV[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int k = 0; k < 3; k++) s += M[3 * i + k] * V[3 * k + j];
            MV[3 * i + j] = s / sqrt(A[3 * j + j]);
        }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int k = 0; k < 3; k++) s += MV[3 * i + k] * V[3 * j + k];
            R[3 * i + j] = s;
        }
}

// apriltag: homography_to_pose(H, -fx, fy, cx, cy), t scaled by tagsize / 2, then diag(1,-1,-1).
static void homography_pose(const matd_t* H, double tagsize, double R[9], double t[3]) {
    const double fxn = -fx;
    double R20 = MATD_EL(H, 2, 0), R21 = MATD_EL(H, 2, 1), TZ = MATD_EL(H, 2, 2);
    double R00 = (MATD_EL(H, 0, 0) - cx * R20) / fxn;
    double R01 = (MATD_EL(H, 0, 1) - cx * R21) / fxn;
    double TX = (MATD_EL(H, 0, 2) - cx * TZ) / fxn;
    double R10 = (MATD_EL(H, 1, 0) - cy * R20) / fy;
    double R11 = (MATD_EL(H, 1, 1) - cy * R21) / fy;
    double TY = (MATD_EL(H, 1, 2) - cy * TZ) / fy;
    // apriltag uses sqrtf here (geometric mean of the two column lengths)
    double length1 = sqrtf(R00 * R00 + R10 * R10 + R20 * R20);
    double length2 = sqrtf(R01 * R01 + R11 * R11 + R21 * R21);
    double s = 1.0 / sqrtf(length1 * length2);
    if (TZ > 0) s *= -1;  // tag in front of a camera looking along -z
    R20 *= s, R21 *= s, TZ *= s, R00 *= s, R01 *= s, TX *= s, R10 *= s, R11 *= s, TY *= s;
    double M[9] = {R00, R01, R10 * R21 - R20 * R11, R10, R11, R20 * R01 - R00 * R21,
                   R20, R21, R00 * R11 - R10 * R01};
    double Rm[9];
    nearest_rotation(M, Rm);
    const double flip[3] = {1, -1, -1};
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) R[3 * i + j] = flip[i] * Rm[3 * i + j];
    }
    t[0] = flip[0] * TX * tagsize / 2, t[1] = flip[1] * TY * tagsize / 2, t[2] = flip[2] * TZ * tagsize / 2;
}

// ---- the two methods on one case; pose in our frame (R_ours, marker centre) ----

static apriltag_detection_t det;
static apriltag_detection_info_t info;

static int pose_estimate_tag_pose(const double q[8], double R[9], double t[3]) {
    if (!fill_detection(q, &det)) return 0;
    apriltag_pose_t pose;
    estimate_tag_pose(&info, &pose);
    memcpy(R, pose.R->data, 9 * sizeof(double));
    memcpy(t, pose.t->data, 3 * sizeof(double));
    free(pose.R);  // matd_destroy is free() on a flexible-array matd_t; not exported by the .so
    free(pose.t);
    return 1;
}

static int pose_homography(const double q[8], double R[9], double t[3]) {
    if (!fill_detection(q, &det)) return 0;
    homography_pose(det.H, info.tagsize, R, t);
    return 1;
}

typedef int (*Method)(const double q[8], double R[9], double t[3]);
static const char* NAMES[2] = {"apriltag_estimate_tag_pose", "apriltag_homography"};
static const Method METHODS[2] = {pose_estimate_tag_pose, pose_homography};

static double rotation_error_deg(const double A[9], const double B[9]) {
    double rel[9];  // A^T B
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int k = 0; k < 3; k++) s += A[3 * k + i] * B[3 * k + j];
            rel[3 * i + j] = s;
        }
    double sx = rel[7] - rel[5], sy = rel[2] - rel[6], sz = rel[3] - rel[1];
    double sn = sqrt(sx * sx + sy * sy + sz * sz) / 2, cs = (rel[0] + rel[4] + rel[8] - 1) / 2;
    return atan2(sn, cs) * 180 / 3.14159265358979323846;
}

static double now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e9 + ts.tv_nsec;
}

static int cmp_double(const void* a, const void* b) {
    double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

int main(int argc, char** argv) {
    int exact = argc > 1 && strcmp(argv[1], "--exact") == 0;
    const char* path = argc > 1 + exact ? argv[1 + exact] : "target/accuracy/corners.csv";
    const char* out_path = !exact && argc > 2 ? argv[2] : NULL;
    size_t n;
    Case* cases = read_cases(path, &n);
    if (n == 0) {
        fprintf(stderr, "no cases in %s\n", path);
        return 1;
    }
    det.H = new_mat(3, 3);
    info.det = &det;
    info.tagsize = side;  // mm, so t comes out in mm
    info.fx = fx, info.fy = fy, info.cx = cx, info.cy = cy;

    if (exact) {
        // Project the true corners: our centred frame has TL (-h,-h), TR (h,-h), BR (h,h), BL (-h,h).
        const double h = side / 2, off[4][2] = {{-h, -h}, {h, -h}, {h, h}, {-h, h}};
        for (size_t i = 0; i < n; i++) {
            Case* c = &cases[i];
            for (int k = 0; k < 4; k++) {
                double p[3];
                for (int r = 0; r < 3; r++) p[r] = c->c[r] + c->R[3 * r] * off[k][0] + c->R[3 * r + 1] * off[k][1];
                c->q[2 * k] = fx * p[0] / p[2] + cx;
                c->q[2 * k + 1] = fy * p[1] / p[2] + cy;
            }
        }
        for (int m = 0; m < 2; m++) {
            double max_rot = 0, max_pos = 0;
            for (size_t i = 0; i < n; i++) {
                double R[9], t[3];
                if (!METHODS[m](cases[i].q, R, t)) {
                    max_rot = max_pos = INFINITY;
                    continue;
                }
                double e = rotation_error_deg(R, cases[i].R);
                double d = sqrt(pow(t[0] - cases[i].c[0], 2) + pow(t[1] - cases[i].c[1], 2) +
                                pow(t[2] - cases[i].c[2], 2));
                if (e > max_rot) max_rot = e;
                if (d > max_pos) max_pos = d;
            }
            printf("%s exact corners, %zu cases: max rotation error %.3g deg, max position error %.3g mm\n",
                   NAMES[m], n, max_rot, max_pos);
        }
        return 0;
    }

    if (out_path) {
        FILE* out = fopen(out_path, "w");
        if (!out) {
            fprintf(stderr, "cannot write %s\n", out_path);
            return 1;
        }
        fprintf(out, "id,method,r11,r12,r13,r21,r22,r23,r31,r32,r33,cx_mm,cy_mm,cz_mm\n");
        for (int m = 0; m < 2; m++)
            for (size_t i = 0; i < n; i++) {
                double R[9], t[3];
                if (!METHODS[m](cases[i].q, R, t)) {
                    for (int k = 0; k < 9; k++) R[k] = NAN;
                    t[0] = t[1] = t[2] = NAN;
                }
                fprintf(out, "%zu,%s", i, NAMES[m]);
                for (int k = 0; k < 9; k++) fprintf(out, ",%.17g", R[k]);
                fprintf(out, ",%.17g,%.17g,%.17g\n", t[0], t[1], t[2]);
            }
        fclose(out);
        if (argc > 3 && strcmp(argv[3], "--no-timing") == 0) return 0;
    }

    // OpenCV's bench uses 15 rounds after 2 warm-up rounds; estimate_tag_pose costs ~1 ms a call,
    // so it gets 5 rounds after 1 warm-up round (10 s of one core per run).
    static const int ROUNDS[2] = {5, 15}, WARMUP[2] = {1, 2};
    double per_call[15];
    for (int m = 0; m < 2; m++) {
        const int rounds = ROUNDS[m], warmup = WARMUP[m];
        volatile double sink = 0;
        for (int r = 0; r < rounds + warmup; r++) {
            double start = now_ns();
            for (size_t i = 0; i < n; i++) {
                double R[9], t[3];
                METHODS[m](cases[i].q, R, t);
                sink += t[2];
            }
            double ns = now_ns() - start;
            if (r >= warmup) per_call[r - warmup] = ns / n;
        }
        qsort(per_call, rounds, sizeof(double), cmp_double);
        printf("%s %.0f %zu\n", NAMES[m], per_call[rounds / 2], n);
    }
    free(det.H);
    free(cases);
    return 0;
}
