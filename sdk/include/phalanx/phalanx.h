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
#define PHALANX_VERSION_MINOR 1
#define PHALANX_VERSION_PATCH 0
/** Encoded as major * 10000 + minor * 100 + patch. */
#define PHALANX_VERSION (PHALANX_VERSION_MAJOR * 10000 + PHALANX_VERSION_MINOR * 100 + PHALANX_VERSION_PATCH)

#define PHALANX_MAX_SAMPLES 25
#define PHALANX_MAX_SETPOINTS 8
#define PHALANX_GLOVE_FINGERS 5

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

typedef struct phalanx_client phalanx_client;

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
