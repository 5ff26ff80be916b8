/* The joint <-> actuator maths of every RH5 submechanism, one unit at one sample (unit_maps.c).
 *
 * Each unit is one row of a table (float64, ROW_WIDTH columns): kind, dof m, first joint, first actuator, then
 * its constants, written by the Python models (kernels.py, lambda_rrpr.py, spu.py, ankle_sprr.py, serial.py),
 * which also hold the geometry and turn a failure code into its reason:
 *   RRPR    phi0, k0, k1, r12, sign, moment_arm_max
 *   SPU     l0[2], jinv0[4], mode, tolerance, max_iterations, max_step, legs 2 x (b[3], e0[3])
 *   SPRR    as SPU, legs 2 x (s[3], f0[3], a0[3], r)
 *   LINEAR  cond(T), T[3][3] (l = T y), Tinv[3][3]
 *   COPY    nothing: m pass-through values (rotary joints; RobotMapper merges neighbours into one row)
 */
#ifndef RH5_UNIT_MAPS_H
#define RH5_UNIT_MAPS_H

#define ROW_WIDTH 48
#define MAX_DOF 3
#define KIND_COPY 0
#define KIND_RRPR 1
#define KIND_SPU 2
#define KIND_SPRR 3
#define KIND_LINEAR 4
#define FK_NOT_CONVERGED (-1)
#define FK_WRONG_MODE (-2)
#define FK_UNREACHABLE (-3)
#define FK_SINGULAR (-4)

/* One unit at one pose: lengths l, Jacobian J (row-major m x m) and acceleration bias J-dot y-dot. */
typedef struct {
    double l[MAX_DOF], j[MAX_DOF * MAX_DOF], b[MAX_DOF];
} Pose;

/* The pose of one unit at joints y (the bias only when yd is given). */
void unit_pose(const double *row, const double *y, const double *yd, Pose *p);

/* The unit's condition number at the pose: h_max / |J| (RRPR), cond_2(J) (2x2), cond(T), 1 (COPY). */
double unit_condition(const double *row, const Pose *p);

/* The arrays of one sample, NULL where not given: ik (q, v, a, tau, l, ld, ldd, f), fk (l, ld, f, q_guess, q, v,
 * tau). A unit map writes its block and returns its status (< 0: failed). */
typedef int (*UnitMap)(const double *row, double *const *x, double max_condition, double *info);

/* Joints -> actuators of one unit: l, J v, J a + bias, J^-T tau; -1 when the force map is refused. */
int ik_unit(const double *row, double *const *x, double max_condition, double *info);

/* Actuators -> joints of one unit: y, J^-1 ld, J^T f; the iterations, or a FK_* code. */
int fk_unit(const double *row, double *const *x, double max_condition, double *info);

#endif
