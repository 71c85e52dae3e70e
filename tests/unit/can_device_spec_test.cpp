// phalanxd's CAN device spec: can:<interface>[:<node>][@fd|@fd-compact|@classic], validated before anything is opened.
#include <gtest/gtest.h>

#include "phalanx/host/daemon.h"

using phalanx::host::parseCanDevice;
using phalanx::host::RunOptions;
using phalanx::linux_hal::CanLink;
namespace can = phalanx::protocol::can;

TEST(CanDeviceSpec, DefaultsToNodeOneAndCanFd) {
  CanLink::Options o;
  EXPECT_EQ(parseCanDevice("can:can0", o), "");
  EXPECT_EQ(o.ifname, "can0");
  EXPECT_EQ(o.node, 1);
  EXPECT_EQ(o.flavor, can::Flavor::kFd);
  EXPECT_EQ(o.role, can::Role::kHost);
}

TEST(CanDeviceSpec, ReadsNodeAndFlavour) {
  CanLink::Options o;
  EXPECT_EQ(parseCanDevice("can:vcan0:17@classic", o), "");
  EXPECT_EQ(o.ifname, "vcan0");
  EXPECT_EQ(o.node, 17);
  EXPECT_EQ(o.flavor, can::Flavor::kClassic);
  EXPECT_EQ(parseCanDevice("can:vcan1@fd", o), "");
  EXPECT_EQ(o.flavor, can::Flavor::kFd);
  EXPECT_EQ(parseCanDevice("can:vcan1:2@fd-compact", o), "");
  EXPECT_EQ(o.flavor, can::Flavor::kFdCompact);
}

TEST(CanDeviceSpec, RejectsBadNodesModesAndNamesNamingTheProblem) {
  CanLink::Options o;
  EXPECT_NE(parseCanDevice("can:can0:0", o).find("node id '0'"), std::string::npos);
  EXPECT_NE(parseCanDevice("can:can0:64", o).find("1..63"), std::string::npos);
  EXPECT_NE(parseCanDevice("can:can0:x1", o).find("node id"), std::string::npos);
  EXPECT_NE(parseCanDevice("can:can0@turbo", o).find("CAN mode 'turbo'"), std::string::npos);
  EXPECT_NE(parseCanDevice("can:", o).find("interface"), std::string::npos);
  EXPECT_NE(parseCanDevice("can:averyveryverylongname", o).find("interface"), std::string::npos);
}

TEST(CanDeviceSpec, ValidateAcceptsCanDevicesAndReportsBadOnes) {
  RunOptions opt;
  opt.device = "can:vcan0:3@classic";
  EXPECT_EQ(phalanx::host::validate(opt), "");
  opt.device = "can:vcan0:99";
  EXPECT_NE(phalanx::host::validate(opt), "");
  opt.device = "spi:1234";  // (usb: is a device kind since the USB transport)
  EXPECT_NE(phalanx::host::validate(opt).find("can:can0"), std::string::npos);
}
