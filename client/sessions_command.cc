// `visloc sessions`: the live robots of a server (its Fleet service, fed by the registry its
// sessions update frame by frame): map, status, position, inliers, latency, frame rate, and how
// long a robot has been without a pose. Once, or with --watch a snapshot every interval (on a
// terminal the table is redrawn in place; otherwise each snapshot is printed after the last, one
// JSON object a line with --json).

#include <grpcpp/grpcpp.h>

#include <cstdio>
#include <iostream>
#include <string>

#include "client/commands.h"
#include "client/connection.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::cli {
namespace {

// "STATUS_TRACKING" -> "tracking".
std::string StatusText(v1::Status status) {
  std::string name = v1::Status_Name(status);
  if (StartsWith(name, "STATUS_")) name = name.substr(7);
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return name;
}

double SecondsBetween(int64_t from_ns, int64_t to_ns) { return (to_ns - from_ns) * 1e-9; }

std::string ToJson(const v1::ListSessionsResponse& fleet, const std::string& server) {
  JsonWriter json;
  json.BeginObject()
      .Field("server", server)
      .Field("max_sessions", static_cast<int64_t>(fleet.max_sessions()))
      .Key("sessions")
      .BeginArray();
  for (const v1::SessionSummary& s : fleet.sessions()) {
    json.BeginObject()
        .Field("session", s.session_id())
        .Field("robot", s.robot_id())
        .Field("map", s.map_name())
        .Field("status", StatusText(s.status()))
        .Field("has_pose", s.has_pose());
    if (s.has_pose()) {
      const v1::Pose& p = s.map_from_cam();
      json.Key("map_from_cam").BeginArray();
      for (double v : {p.tx(), p.ty(), p.tz(), p.qx(), p.qy(), p.qz(), p.qw()}) json.Value(v);
      json.EndArray().Field("position_sigma_m", s.position_sigma_m());
    }
    json.Field("inliers", static_cast<int64_t>(s.inliers()))
        .Field("inlier_ratio", s.inlier_ratio())
        .Field("frames", s.frames())
        .Field("localized", s.localized())
        .Field("skipped", s.skipped())
        .Field("errors", s.errors())
        .Field("server_ms", s.server_ms())
        .Field("frame_rate_hz", s.frame_rate_hz())
        .Field("seconds_since_last_frame",
               s.last_frame_unix_ns()
                   ? SecondsBetween(s.last_frame_unix_ns(), fleet.server_time_unix_ns())
                   : -1.0)
        .Field("seconds_without_pose",
               s.without_pose_since_unix_ns()
                   ? SecondsBetween(s.without_pose_since_unix_ns(), fleet.server_time_unix_ns())
                   : 0.0)
        .EndObject();
  }
  json.EndArray().EndObject();
  return json.str();
}

std::string Table(const v1::ListSessionsResponse& fleet, const std::string& server) {
  std::string out =
      StrCat(fleet.sessions_size(), " of ", fleet.max_sessions(), " sessions on ", server, "\n");
  if (fleet.sessions_size() == 0) return out;
  char line[256];
  std::snprintf(line, sizeof(line), "%5s %-14s %-12s %-12s %24s %8s %6s %8s %7s %7s %9s\n", "ID",
                "ROBOT", "MAP", "STATUS", "POSITION (m)", "INLIERS", "RATIO", "FRAMES", "MS", "HZ",
                "NO POSE");
  out += line;
  for (const v1::SessionSummary& s : fleet.sessions()) {
    const std::string position = s.has_pose() ? StrCat(FormatFixed(s.map_from_cam().tx(), 2), " ",
                                                       FormatFixed(s.map_from_cam().ty(), 2), " ",
                                                       FormatFixed(s.map_from_cam().tz(), 2))
                                              : "-";
    const std::string without_pose =
        s.without_pose_since_unix_ns()
            ? FormatFixed(
                  SecondsBetween(s.without_pose_since_unix_ns(), fleet.server_time_unix_ns()), 1) +
                  " s"
            : "-";
    std::snprintf(line, sizeof(line),
                  "%5llu %-14.14s %-12.12s %-12s %24s %8u %6.2f %8llu %7.1f %7.1f %9s\n",
                  static_cast<unsigned long long>(s.session_id()),
                  s.robot_id().empty() ? "-" : s.robot_id().c_str(), s.map_name().c_str(),
                  StatusText(s.status()).c_str(), position.c_str(), s.inliers(), s.inlier_ratio(),
                  static_cast<unsigned long long>(s.frames()), s.server_ms(), s.frame_rate_hz(),
                  without_pose.c_str());
    out += line;
  }
  return out;
}

void Print(const v1::ListSessionsResponse& fleet, const std::string& server, bool json,
           bool redraw) {
  if (json) {
    std::cout << ToJson(fleet, server) << std::endl;
    return;
  }
  if (redraw) std::cout << "\33[H\33[2J";  // Home and clear: the table in place.
  std::cout << Table(fleet, server) << std::flush;
}

}  // namespace

int RunSessions(const Args& args) {
  Connection server;
  bool watch = false, json = false;
  int interval_ms = 500, count = 0;
  ArgParser parser("visloc sessions",
                   "Lists the live robot sessions of a visloc-server: map, status, position, "
                   "inliers and inlier ratio, server time per frame, frame rate, and how long a "
                   "robot has been without a pose. With --watch, a snapshot every interval until "
                   "interrupted (or --count snapshots).");
  server.AddFlags(parser);
  parser.AddSwitch("watch", &watch, "keep printing snapshots");
  parser.AddFlag("interval-ms", &interval_ms, "with --watch: time between snapshots");
  parser.AddFlag("count", &count, "with --watch: stop after this many snapshots (0: never)");
  parser.AddSwitch("json", &json, "one JSON object per snapshot (a line each)");
  if (!parser.Parse(args, std::cout)) return 0;
  server.ApplyEnvironment();
  if (interval_ms < 50) throw UsageError("--interval-ms must be at least 50");
  if (count < 0) throw UsageError("--count must not be negative");
  auto stub = v1::Fleet::NewStub(server.OpenChannel());
  grpc::ClientContext context;
  server.Prepare(&context);
  if (!watch) {
    v1::ListSessionsResponse fleet;
    CheckCall(stub->ListSessions(&context, v1::ListSessionsRequest(), &fleet), server.server);
    Print(fleet, server.server, json, false);
    return 0;
  }
  v1::WatchSessionsRequest request;
  request.set_interval_ms(static_cast<uint32_t>(interval_ms));
  auto reader = stub->WatchSessions(&context, request);
  v1::ListSessionsResponse fleet;
  const bool redraw = ShowProgress() && !json;
  int printed = 0;
  while (reader->Read(&fleet)) {
    Print(fleet, server.server, json, redraw);
    if (count > 0 && ++printed >= count) {
      context.TryCancel();
      break;
    }
  }
  const grpc::Status status = reader->Finish();
  if (count > 0 && printed >= count) return 0;
  CheckCall(status, server.server);
  return 0;
}

}  // namespace visloc::cli
