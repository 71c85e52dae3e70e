#pragma once
/// Who may be on either end of the control-API socket (docs/security.md):
/// - the socket lives in a private directory (writable by its owner only, owned by the daemon's user or root,
///   not a symlink), so nobody else can create the socket first and have clients talk to them;
/// - the daemon checks each client's credentials (SO_PEERCRED): its own uid, root, or a member of the API group;
/// - the client checks the server's: root or the client's own uid (or one it was told to trust).
#include <sys/types.h>

#include <string>

namespace phalanx::host::api {

/// $XDG_RUNTIME_DIR/phalanxd.sock; else /run/phalanx/phalanxd.sock for root; else /tmp/phalanxd-<uid>/phalanxd.sock.
std::string defaultSocketPath();

/// Makes the socket's directory ready: creates it (mode 0700, or 0750 with group `group` when group >= 0) when
/// `socket_path` is the default path and the directory is missing; then checks that it is a real directory (not
/// a symlink), owned by this process's user or root, and writable by nobody else. "" or the problem.
std::string prepareSocketDirectory(const std::string& socket_path, long group);

/// The daemon's check of a connected client: "" when its uid is ours or root, or it is in `group` (primary or
/// supplementary; group < 0: this process's effective group); otherwise the refusal, naming the uid.
std::string refusePeer(int fd, long group);

/// The client's check of the server it connected to: "" when its uid is root, the client's own uid, or
/// `trusted_uid` (>= 0); otherwise the refusal, naming the path and the uid.
std::string refuseServer(int fd, const std::string& socket_path, long trusted_uid);

}  // namespace phalanx::host::api
