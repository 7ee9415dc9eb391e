// `visloc jobs --server ADDR [--json]`: the server's mapping jobs (maps built from streamed
// stereo runs, `visloc map build --server`): the running ones with their frames, keyframes,
// points and state, and the most recent ended ones with their outcome.

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
#include "proto/mapping_convert.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::cli {
namespace {

// How long a job ran (or has run), seconds.
double Seconds(const v1::MappingJob& job, int64_t now_ns) {
  return ((job.ended_unix_ns() ? job.ended_unix_ns() : now_ns) - job.started_unix_ns()) * 1e-9;
}

std::string ToJson(const v1::ListJobsResponse& list, const std::string& server) {
  JsonWriter json;
  json.BeginObject()
      .Field("server", server)
      .Field("max_jobs", static_cast<int64_t>(list.max_jobs()))
      .Key("jobs")
      .BeginArray();
  for (const v1::MappingJob& job : list.jobs()) {
    json.BeginObject()
        .Field("job", job.job_id())
        .Field("map", job.map_name())
        .Field("robot", job.robot_id())
        .Field("state", proto::MappingStateText(job.state()))
        .Field("running", job.ended_unix_ns() == 0)
        .Field("frames", job.frames())
        .Field("keyframes", static_cast<int64_t>(job.keyframes()))
        .Field("points", job.points())
        .Field("tracking_failures", static_cast<int64_t>(job.tracking_failures()))
        .Field("seconds", Seconds(job, list.server_time_unix_ns()))
        .Field("error", job.error())
        .Field("note", job.note())
        .EndObject();
  }
  json.EndArray().EndObject();
  return json.str();
}

std::string Table(const v1::ListJobsResponse& list, const std::string& server) {
  int running = 0;
  for (const v1::MappingJob& job : list.jobs()) running += job.ended_unix_ns() == 0;
  std::string out = StrCat(running, " of ", list.max_jobs(), " mapping jobs running on ", server,
                           ", ", list.jobs_size() - running, " ended\n");
  if (list.jobs_size() == 0) return out;
  char line[512];
  std::snprintf(line, sizeof(line), "%5s %-16s %-14s %-11s %7s %9s %8s %6s %8s  %s\n", "JOB", "MAP",
                "ROBOT", "STATE", "FRAMES", "KEYFRAMES", "POINTS", "LOST", "SECONDS",
                "ERROR OR NOTE");
  out += line;
  for (const v1::MappingJob& job : list.jobs()) {
    std::snprintf(
        line, sizeof(line), "%5llu %-16.16s %-14.14s %-11s %7llu %9u %8llu %6u %8.1f  %s\n",
        static_cast<unsigned long long>(job.job_id()), job.map_name().c_str(),
        job.robot_id().empty() ? "-" : job.robot_id().c_str(),
        proto::MappingStateText(job.state()).c_str(), static_cast<unsigned long long>(job.frames()),
        job.keyframes(), static_cast<unsigned long long>(job.points()), job.tracking_failures(),
        Seconds(job, list.server_time_unix_ns()),
        (job.error().empty() ? job.note() : job.error()).c_str());
    out += line;
  }
  return out;
}

}  // namespace

int RunJobs(const Args& args) {
  Connection server;
  bool json = false;
  ArgParser parser("visloc jobs",
                   "Lists the mapping jobs of a visloc-server (maps built from streamed stereo "
                   "runs, `visloc map build --server`): running ones with their frames, "
                   "keyframes, points and state, and the most recent ended ones with their "
                   "outcome (published, failed or abandoned, and why).");
  server.AddFlags(parser);
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  server.ApplyEnvironment();
  auto stub = v1::Mapping::NewStub(server.OpenChannel());
  grpc::ClientContext context;
  server.Prepare(&context);
  v1::ListJobsResponse list;
  CheckCall(stub->ListJobs(&context, v1::ListJobsRequest{}, &list), server.server);
  std::cout << (json ? ToJson(list, server.server) + "\n" : Table(list, server.server));
  return 0;
}

}  // namespace visloc::cli
