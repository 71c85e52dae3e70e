/* The C ABI: press one glove finger with a constant pad force for a number of cycles (docs/sdk.md).
 *   glove_press SOCKET FINGER FORCE_N CYCLES [DEADLINE_MS] */
#include <phalanx/phalanx.h>
#include <stdio.h>
#include <stdlib.h>

struct press {
  int finger;
  float force_N;
  long cycles_left;
};

static int servo(const phalanx_state* s, float* setpoints, void* user) {
  struct press* p = (struct press*)user;
  int i;
  (void)s;
  for (i = 0; i < PHALANX_GLOVE_FINGERS; ++i) setpoints[i] = 0.0f;
  setpoints[p->finger] = p->force_N;
  return --p->cycles_left <= 0; /* non-zero stops */
}

int main(int argc, char** argv) {
  phalanx_client* c;
  phalanx_device_info info;
  phalanx_state last;
  struct press p;
  int rc;
  unsigned deadline_ms = 20;
  if (argc != 5 && argc != 6) {
    fprintf(stderr, "usage: glove_press SOCKET FINGER FORCE_N CYCLES [DEADLINE_MS]\n");
    return 2;
  }
  p.finger = atoi(argv[2]);
  p.force_N = (float)atof(argv[3]);
  p.cycles_left = atol(argv[4]);
  if (argc == 6) deadline_ms = (unsigned)atoi(argv[5]);
  if (p.finger < 0 || p.finger >= PHALANX_GLOVE_FINGERS) return 2;
  c = phalanx_connect(argv[1], deadline_ms, PHALANX_FALLBACK_SAFE);
  if (c == NULL) {
    fprintf(stderr, "glove_press: %s\n", phalanx_last_error());
    return 3;
  }
  phalanx_get_device_info(c, &info);
  printf("glove_press: libphalanx %d, device %s, %u setpoints, limit %.1f, %u Hz, deadline %u ms\n",
         phalanx_version(), info.device_name, info.setpoint_count, (double)info.setpoint_limit, info.rate_hz,
         info.deadline_ms);
  rc = phalanx_run_servo(c, servo, &p, &last);
  printf("glove_press: %s, sent %.3f N, cause %s\n", rc == PHALANX_OK ? "done" : phalanx_last_error(),
         (double)last.setpoint_sent[p.finger], phalanx_force_off_cause_name(last.force_off_cause));
  phalanx_disconnect(c);
  return rc == PHALANX_OK ? 0 : 1;
}
