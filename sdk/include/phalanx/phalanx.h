/* libphalanx: the C ABI of the Phalanx client library (docs/sdk.md).
 *
 * A thin, stable layer over the C++ API (phalanx/client.hpp): an opaque handle, phalanx_* functions returning
 * 0 on success and a negative PHALANX_E* code on failure (phalanx_last_error() says why), plain structs with SI
 * field names. The daemon (phalanxd --client-socket PATH) checks every command against the device's and the
 * patient's limits and forces the device safe (or transparent) when the client misses its deadline.
 */
#ifndef PHALANX_PHALANX_H
#define PHALANX_PHALANX_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define PHALANX_VERSION_MAJOR 0
#define PHALANX_VERSION_MINOR 2
#define PHALANX_VERSION_PATCH 0
/** Encoded as major * 10000 + minor * 100 + patch. */
#define PHALANX_VERSION (PHALANX_VERSION_MAJOR * 10000 + PHALANX_VERSION_MINOR * 100 + PHALANX_VERSION_PATCH)

#define PHALANX_MAX_SAMPLES 25
#define PHALANX_MAX_SETPOINTS 8
#define PHALANX_GLOVE_FINGERS 5
#define PHALANX_MAX_MODEL_VALUES 10
#define PHALANX_MAX_SPRINGS 5

enum {
  PHALANX_OK = 0,
  PHALANX_ECONNECT = -1,   /* the socket could not be reached (path, permissions, peer refused) */
  PHALANX_EREFUSED = -2,   /* the daemon refused the request (version, busy, bad deadline): see the message */
  PHALANX_EARG = -3,       /* a bad argument (NULL, count, wrong device for the call) */
  PHALANX_ETIMEOUT = -4,   /* no new state within the wait */
  PHALANX_EFORCED_OFF = -5 /* the daemon forced this client off; state.force_off_cause says why */
};

enum { PHALANX_FALLBACK_SAFE = 0, PHALANX_FALLBACK_TRANSPARENT = 1 };
enum { PHALANX_MODE_SAFE = 0, PHALANX_MODE_TRANSPARENT = 1, PHALANX_MODE_SETPOINT = 2 };
/* state.control */
enum { PHALANX_CONTROL_NOT_YET = 0, PHALANX_CONTROL_CLIENT = 1, PHALANX_CONTROL_OTHER_SOURCE = 2,
       PHALANX_CONTROL_FORCED_OFF = 3, PHALANX_CONTROL_STOPPED = 4 };
/* state.force_off_cause */
enum { PHALANX_CAUSE_NONE = 0, PHALANX_CAUSE_CLIENT_TIMEOUT = 1, PHALANX_CAUSE_INVALID_COMMAND = 2,
       PHALANX_CAUSE_LIMIT = 3, PHALANX_CAUSE_DEVICE_FAULT = 4, PHALANX_CAUSE_ESTOP = 5, PHALANX_CAUSE_LINK_LOSS = 6,
       PHALANX_CAUSE_DAEMON_STOP = 7 };

/* command.kind: what the command carries; model-level kinds are converted by the daemon's device model, then
 * checked by the limits stage like raw setpoints (docs/sdk.md "Model level"). */
enum { PHALANX_COMMAND_RAW = 0, PHALANX_COMMAND_GLOVE_FINGERTIP_FORCE = 1, PHALANX_COMMAND_SEA_FINGER_TORQUE = 2,
       PHALANX_COMMAND_PEN_WRENCH = 3 };
/* state.rendered: what the daemon sent for this client this cycle */
enum { PHALANX_RENDERED_NOTHING = 0, PHALANX_RENDERED_COMMAND = 1, PHALANX_RENDERED_FALLBACK_SPRING = 2,
       PHALANX_RENDERED_REPEAT = 3 };

typedef struct phalanx_client phalanx_client;

/* One spring-damper of the compliant fallback. glove: fingertip (x, y) in the finger's base frame, m, N/m,
 * N·s/m; SEA: target[0] joint flexion rad (element 0 MCP, 1 PIP), N·m/rad, N·m·s/rad; pen: pen centre, m,
 * N/m, N·s/m (element 0; force only). */
typedef struct {
  float target[3];
  float stiffness;
  float damping;
} phalanx_spring;

/* Rendered by the daemon in every cycle without a fresh command from this client, until its deadline. */
typedef struct {
  int enabled;                              /* 0: the daemon repeats the last command instead */
  phalanx_spring element[PHALANX_MAX_SPRINGS];
} phalanx_fallback_spring;

typedef struct {
  int mode;                                 /* PHALANX_MODE_* */
  int kind;                                 /* PHALANX_COMMAND_* */
  float setpoint[PHALANX_MAX_SETPOINTS];    /* kind RAW */
  float model[PHALANX_MAX_MODEL_VALUES];    /* glove: (fx, fy) per finger, N; SEA: τ_f MCP, PIP, N·m (+ extends);
                                               pen: force xyz N, moment xyz N·m at the pen centre */
  phalanx_fallback_spring fallback;
} phalanx_command;

/* Model-level state, computed by the daemon from its device models (only the connected device's is filled). */
typedef struct {
  float joint_rad[5][3];           /* θ1..θ3 per finger (flexion negative, docs/glove-model.md) */
  float fingertip[5][3];           /* x_m, y_m, phi_rad in the finger's base frame */
  float fingertip_velocity[5][2];  /* m/s */
  float pad_force_N[5];            /* + pushes the fingertip towards extension */
  uint8_t valid[5];
} phalanx_glove_model;
typedef struct {
  float flexion_rad[3];            /* MCP, PIP, DIP flexion (+ flexes) */
  float flexion_rate_rad_s[3];
  float finger_torque_Nm[2];       /* MCP, PIP finger torque τ̂_f = J_n^{-T} τ̂_j (+ extends) */
  float exo_torque_Nm[2];          /* measured SEA torques */
  uint8_t valid;
} phalanx_sea_model;
typedef struct {
  float centre_m[3], axis[3], tip_m[3];
  float theta_x_rad, theta_z_rad;
  float velocity_m_s[3];           /* of the centre */
  float force_N[3], torque_Nm[3];  /* measured wrench at the centre (from the measured motor torques) */
  uint8_t valid;
} phalanx_pen_model;

typedef struct {
  char device_name[16];       /* "glove5", "sea_finger", "pantograph" */
  int device_type;            /* 1 glove5, 2 sea_finger, 3 pantograph */
  unsigned setpoint_count;
  unsigned sample_count;
  float setpoint_limit;       /* |setpoint| device limit, SI (glove: N of pad force) */
  unsigned rate_hz;           /* the daemon's loop rate */
  unsigned deadline_ms;       /* the deadline the daemon enforces on this client */
  uint32_t firmware_build_id;
} phalanx_device_info;

typedef struct {
  uint64_t cycle;
  uint64_t daemon_time_ns;    /* CLOCK_MONOTONIC of the daemon cycle that published this state */
  uint64_t telemetry_rx_ns;   /* CLOCK_MONOTONIC when the telemetry frame arrived */
  uint64_t device_time_us;
  uint16_t telemetry_seq;
  uint8_t device_mode;        /* PHALANX_MODE_* the device reports */
  uint16_t fault_bits;
  int control;                /* PHALANX_CONTROL_* */
  int force_off_cause;        /* PHALANX_CAUSE_* */
  uint32_t commands_used, refused_invalid, refused_other_source, limited, force_offs;
  float achieved_rate_hz;     /* the client's commands per second the daemon received, last second */
  float sample[PHALANX_MAX_SAMPLES];          /* telemetry samples, SI (glove: 15 angles rad, 5 pad forces N, 5 duty) */
  float setpoint_sent[PHALANX_MAX_SETPOINTS]; /* what the daemon sent (after limits) */
  uint32_t model_saturated;   /* cycles a model-level command was scaled by the device model's saturation */
  uint32_t fallback_cycles;   /* cycles the daemon rendered this client's fallback spring */
  int rendered;               /* PHALANX_RENDERED_* this cycle */
  float model_scale;          /* fraction of the model-level command delivered this cycle */
  phalanx_glove_model glove;
  phalanx_sea_model sea;
  phalanx_pen_model pen;
  uint32_t command_seq_used;  /* the number of this client's command the cycle sent (its n-th command: n), 0: none */
} phalanx_state;

/* Servo callback: fill setpoints[0..setpoint_count) from state; return non-zero to stop. */
typedef int (*phalanx_servo_fn)(const phalanx_state* state, float* setpoints, void* user);

int phalanx_version(void);
/* Connect and negotiate; NULL on failure (phalanx_last_error()). fallback: PHALANX_FALLBACK_*. */
phalanx_client* phalanx_connect(const char* socket_path, unsigned deadline_ms, int fallback);
/* Hand control back cleanly (the daemon's built-in controller resumes) and free the handle. */
void phalanx_disconnect(phalanx_client* c);
const char* phalanx_last_error(void);
int phalanx_get_device_info(const phalanx_client* c, phalanx_device_info* out);
/* Polling: the newest state (PHALANX_ETIMEOUT if none was published yet). */
int phalanx_get_state(phalanx_client* c, phalanx_state* out);
/* Wait up to timeout_ms for a state newer than the last one read. */
int phalanx_wait_state(phalanx_client* c, phalanx_state* out, int timeout_ms);
/* Raw per-channel setpoints (count must equal setpoint_count), mode PHALANX_MODE_*. */
int phalanx_set_setpoints(phalanx_client* c, const float* setpoints, unsigned count, int mode);
/* glove5: fingertip pad forces in N (positive resists flexion), thumb..little. */
int phalanx_glove_set_fingertip_forces(phalanx_client* c, const double force_N[PHALANX_GLOVE_FINGERS]);
/* Any command (raw or model-level, with its fallback). */
int phalanx_set_command(phalanx_client* c, const phalanx_command* cmd);
/* sea_finger: finger joint torques MCP, PIP (N·m, + extends) through J_n; fallback may be NULL. */
int phalanx_sea_set_finger_torques(phalanx_client* c, const double tau_Nm[2], const phalanx_fallback_spring* fallback);
/* pantograph: the pen wrench at its centre (force N, moment N·m, base frame); fallback may be NULL. */
int phalanx_pen_set_wrench(phalanx_client* c, const double force_N[3], const double torque_Nm[3],
                           const phalanx_fallback_spring* fallback);
/* Servo callback with a full command (pre-filled with the previous one); return non-zero to stop. */
typedef int (*phalanx_servo_command_fn)(const phalanx_state* state, phalanx_command* cmd, void* user);
int phalanx_run_servo_command(phalanx_client* c, phalanx_servo_command_fn fn, void* user, phalanx_state* last);
/* glove5: fingertip pose (x_m, y_m, phi_rad) of finger 0..4 in its base frame, from the state's mechanism
 * angles and the default glove geometry (docs/glove-model.md). */
int phalanx_glove_fingertip(const phalanx_state* s, int finger, double pose[3]);
/* Run the servo callback once per daemon cycle until it returns non-zero (returns 0) or force goes off
 * (returns PHALANX_EFORCED_OFF; the last state is in *last if last != NULL). */
int phalanx_run_servo(phalanx_client* c, phalanx_servo_fn fn, void* user, phalanx_state* last);
const char* phalanx_force_off_cause_name(int cause);

#ifdef __cplusplus
}
#endif

#endif /* PHALANX_PHALANX_H */
