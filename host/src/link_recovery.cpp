#include "phalanx/host/link_recovery.h"

#include <algorithm>
#include <cstdio>

namespace phalanx::host {

LinkRecovery::LinkRecovery(RecoveryLink& link, HostSession& session, protocol::DeviceType type,
                           std::vector<std::pair<uint16_t, float>> startup_params, LinkRecoveryOptions opt,
                           NewSessionId new_id, Log log, uint64_t start_ns)
    : link_(link),
      session_(session),
      type_(type),
      params_(std::move(startup_params)),
      opt_(opt),
      new_id_(std::move(new_id)),
      log_(std::move(log)),
      start_ns_(start_ns) {}

void LinkRecovery::sendHello(uint64_t now_ns) {
  session_.sendHello(new_id_(), type_);
  link_.flush();
  phase_ns_ = now_ns;
}

void LinkRecovery::sendParam(uint64_t now_ns) {
  session_.sendParamSet(params_[param_index_].first, params_[param_index_].second);
  phase_ns_ = now_ns;
}

LinkRecovery::Step LinkRecovery::step(uint64_t now_ns) {
  char msg[256];
  if (phase_ == Phase::kUp) {
    if (!link_.lost()) return Step::kControl;
    ++stats_.outages;
    lost_ns_ = now_ns;
    std::snprintf(msg, sizeof msg,
                  "link lost at t=%.3f s (%s): no commands are sent; the device's command timeout takes it to its "
                  "safe state; reconnecting",
                  since(now_ns, start_ns_), link_.describe().c_str());
    log_(msg);
    link_.drop();
    phase_ = Phase::kDown;
    next_reopen_ns_ = now_ns;  // first attempt at once, then every reopen period
  }
  ++stats_.cycles_offline;
  link_.flush();
  if (phase_ != Phase::kDown && link_.lost()) {
    link_.drop();
    phase_ = Phase::kDown;  // lost again before control resumed
    next_reopen_ns_ = now_ns + opt_.reopen_period_ns;
    log_("link lost again before control resumed; reconnecting");
    return Step::kOffline;
  }
  switch (phase_) {
    case Phase::kDown:
      if (now_ns >= next_reopen_ns_) {
        next_reopen_ns_ = now_ns + opt_.reopen_period_ns;
        if (link_.reopen().empty()) {
          session_.resyncStream();  // byte streams: the frame cut by the unplug is not a rejected frame
          sendHello(now_ns);
          phase_ = Phase::kHandshake;
          std::snprintf(msg, sizeof msg, "link back at t=%.3f s after %.3f s (%s); new handshake",
                        since(now_ns, start_ns_), since(now_ns, lost_ns_), link_.describe().c_str());
          log_(msg);
        }
      }
      break;
    case Phase::kHandshake:
      if (session_.handshake() == HandshakeResult::kOk) {
        if (session_.layout()->type != type_) {
          error_ = "after reconnect: a different device answered (" + std::string(session_.layout()->name) + ")";
          return Step::kFailed;
        }
        telemetry_at_handshake_ = session_.stats().telemetry_received;
        param_index_ = 0;
        phase_ = params_.empty() ? Phase::kFirstTelemetry : Phase::kParams;
        if (phase_ == Phase::kParams) sendParam(now_ns);
      } else if (session_.handshake() != HandshakeResult::kPending) {
        error_ = "after reconnect: " + session_.handshakeError();
        return Step::kFailed;
      } else if (now_ns - phase_ns_ > opt_.handshake_timeout_ns) {
        // Nothing answered on the port reopened by name: it may not be the device (another tty took the freed
        // name for a moment, a board still enumerating), or a board that rebooted missed the Hello. Either way
        // close it and open the name again, which sends a new Hello.
        std::snprintf(msg, sizeof msg,
                      "no answer to the handshake within %.1f s on the reopened link (%s): closing it and reopening",
                      since(now_ns, phase_ns_), link_.describe().c_str());
        log_(msg);
        link_.drop();
        phase_ = Phase::kDown;
        next_reopen_ns_ = now_ns;
      }
      break;
    case Phase::kParams:
      if (session_.lastParamValid() && session_.lastParam().param_id == params_[param_index_].first) {
        if (session_.lastParam().status != protocol::ParamStatus::kOk) {
          error_ = "after reconnect: device refused start-up parameter " + std::to_string(params_[param_index_].first);
          return Step::kFailed;
        }
        if (++param_index_ == params_.size()) {
          phase_ = Phase::kFirstTelemetry;
        } else {
          sendParam(now_ns);
        }
      } else if (now_ns - phase_ns_ > opt_.handshake_timeout_ns) {
        sendParam(now_ns);
      }
      break;
    case Phase::kFirstTelemetry:
      if (session_.stats().telemetry_received > telemetry_at_handshake_) {
        stats_.faults_after_reconnect |= session_.latest().fault_bits;
        if (session_.latest().fault_bits != 0 && opt_.clear_faults) {
          log_("clearing faults latched during the outage: " + faultList(session_.latest().fault_bits));
          session_.sendClearFaults();
          link_.flush();
        }
        const double outage_s = since(now_ns, lost_ns_);
        stats_.total_s += outage_s;
        stats_.max_s = std::max(stats_.max_s, outage_s);
        ++stats_.reconnects;
        std::snprintf(msg, sizeof msg, "control resumed at t=%.3f s after an outage of %.3f s (new session)",
                      since(now_ns, start_ns_), outage_s);
        log_(msg);
        phase_ = Phase::kUp;
        // This cycle already counted as offline; commands start with the next one.
      }
      break;
    case Phase::kUp:
      break;
  }
  return Step::kOffline;
}

}  // namespace phalanx::host
