// Checks that the deployment files agree with the code they deploy: docker/Dockerfile,
// docker/compose.yaml and deploy/k8s/*.yaml. Every path they copy or run exists in the
// repository, every binary is one this build makes, every flag is one the binaries' --help
// lists, every port and mount agrees between the server's --listen/--maps, the image, the
// services and the probes, and the fleet has exactly one writer of the shared maps volume.
// Nothing here needs a container engine or a cluster: it runs in every CI build
// (scripts/check-deploy.sh runs it alone).

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

namespace fs = std::filesystem;
using Command = std::vector<std::string>;

const std::string kSource = VISLOC_SOURCE_DIR;

std::set<std::string> FlagsInHelp(const Command& argv) {
  const testing::ProcessResult help = testing::RunProcess(argv);
  EXPECT_EQ(help.exit_code, 0) << help.err;
  static const std::regex kFlag("--([a-z][a-z0-9-]*)");
  std::set<std::string> flags;
  for (std::sregex_iterator it(help.out.begin(), help.out.end(), kFlag), end; it != end; ++it) {
    flags.insert((*it)[1]);
  }
  return flags;
}

const std::set<std::string>& ServerFlags() {
  static const std::set<std::string> flags = FlagsInHelp({VISLOC_SERVER_PATH, "--help"});
  return flags;
}

// "--flag value" pairs of a command line (switches map to ""); unknown flags fail the test.
std::map<std::string, std::string> CheckFlags(const Command& args, size_t from,
                                              const std::set<std::string>& known,
                                              const std::string& where) {
  std::map<std::string, std::string> values;
  for (size_t i = from; i < args.size(); ++i) {
    if (!StartsWith(args[i], "--")) continue;
    const std::string flag = args[i].substr(2);
    EXPECT_TRUE(known.count(flag)) << where << ": --" << flag << " is not a flag of the binary";
    const bool has_value = i + 1 < args.size() && !StartsWith(args[i + 1], "--");
    values[flag] = has_value ? args[i + 1] : "";
  }
  return values;
}

std::map<std::string, std::string> CheckServerArgs(const Command& args, const std::string& where) {
  const auto values = CheckFlags(args, 0, ServerFlags(), where);
  EXPECT_TRUE(values.count("maps")) << where << ": the server needs --maps";
  EXPECT_TRUE(values.count("listen")) << where << ": a container's server must --listen";
  return values;
}

std::string PortOf(const std::string& address) { return address.substr(address.rfind(':') + 1); }

// A `visloc VERB --flags` command (health checks, probes): a real verb with real flags.
// Returns the port its --server names.
// Returns the port of its `address_flag` (--server, or --http for the HTTP readiness check).
std::string CheckVislocCommand(const Command& command, const std::string& where,
                               const std::string& address_flag = "server") {
  EXPECT_GE(command.size(), 2u) << where;
  if (command.size() < 2) return "";
  EXPECT_EQ(command[0], "visloc") << where;
  const auto flags = FlagsInHelp({VISLOC_CLI_PATH, command[1], "--help"});
  EXPECT_FALSE(flags.empty()) << where << ": 'visloc " << command[1] << "' is not a verb";
  const auto values = CheckFlags(command, 2, flags, where);
  EXPECT_TRUE(values.count(address_flag)) << where;
  return values.count(address_flag) ? PortOf(values.at(address_flag)) : "";
}

Command Strings(const YAML::Node& list) {
  Command out;
  for (const auto& item : list) out.push_back(item.as<std::string>());
  return out;
}

// ---------------------------------------------------------------------------- Dockerfile

struct Dockerfile {
  std::vector<std::pair<std::string, std::string>> instructions;  // (KEYWORD, rest)
  std::vector<std::string> All(const std::string& keyword) const {
    std::vector<std::string> found;
    for (const auto& [k, rest] : instructions) {
      if (k == keyword) found.push_back(rest);
    }
    return found;
  }
  std::string Last(const std::string& keyword) const {
    const auto found = All(keyword);
    EXPECT_FALSE(found.empty()) << "the Dockerfile has no " << keyword;
    return found.empty() ? "" : found.back();
  }
};

Dockerfile ParseDockerfile(const std::string& path) {
  Dockerfile file;
  std::istringstream in(ReadFileBytes(path));
  std::string line, logical;
  while (std::getline(in, line)) {
    if (logical.empty() && (line.empty() || line[0] == '#')) continue;
    if (!line.empty() && line.back() == '\\') {  // Continued on the next line.
      logical += line.substr(0, line.size() - 1) + " ";
      continue;
    }
    if (!StartsWith(Trim(line), "#")) logical += line;
    const std::string text(Trim(logical));
    logical.clear();
    if (text.empty()) continue;
    const size_t space = text.find(' ');
    file.instructions.push_back({text.substr(0, space), std::string(Trim(text.substr(space + 1)))});
  }
  return file;
}

// The JSON array form of CMD / ENTRYPOINT / HEALTHCHECK CMD.
Command ExecForm(const std::string& text) {
  const YAML::Node node = YAML::Load(text.substr(text.find('[')));
  return Strings(node);
}

std::string RelativeToBuild(const std::string& binary) {
  return fs::relative(binary, VISLOC_BUILD_DIR).string();
}

TEST(DeploymentConfigTest, DockerfileCopiesAndRunsWhatExists) {
  const Dockerfile docker = ParseDockerfile(kSource + "/docker/Dockerfile");
  for (const std::string& copy : docker.All("COPY")) {
    if (StartsWith(copy, "--from")) continue;
    const auto parts = SplitWhitespace(copy);
    for (size_t i = 0; i + 1 < parts.size(); ++i) {
      EXPECT_TRUE(fs::exists(kSource + "/" + parts[i])) << "COPY " << parts[i];
    }
  }
  static const std::regex kRepoPath("\\b((docker|scripts)/[A-Za-z0-9_.-]+)");
  for (const std::string& run : docker.All("RUN")) {
    for (std::sregex_iterator it(run.begin(), run.end(), kRepoPath), end; it != end; ++it) {
      EXPECT_TRUE(fs::exists(kSource + "/" + (*it)[1].str())) << "RUN uses " << (*it)[1];
    }
  }
  // The binaries the builder stages are where this CMake build puts them.
  std::string all_runs;
  for (const std::string& run : docker.All("RUN")) all_runs += run + "\n";
  EXPECT_NE(all_runs.find("--target visloc-server visloc"), std::string::npos);
  for (const std::string binary : {VISLOC_SERVER_PATH, VISLOC_CLI_PATH}) {
    EXPECT_NE(all_runs.find("/build/" + RelativeToBuild(binary)), std::string::npos) << binary;
  }
  EXPECT_NE(docker.Last("USER"), "root");
  EXPECT_NE(docker.Last("USER"), "0");
}

TEST(DeploymentConfigTest, DockerfilePortsMapsAndHealthCheckAgreeWithTheServer) {
  const Dockerfile docker = ParseDockerfile(kSource + "/docker/Dockerfile");
  EXPECT_EQ(ExecForm(docker.Last("ENTRYPOINT")), Command{"visloc-server"});
  const auto server = CheckServerArgs(ExecForm(docker.Last("CMD")), "Dockerfile CMD");
  const std::string port = docker.Last("EXPOSE");
  EXPECT_EQ(PortOf(server.at("listen")), port);
  EXPECT_EQ(docker.Last("VOLUME"), server.at("maps"));
  const std::string health = docker.Last("HEALTHCHECK");
  ASSERT_NE(health.find("CMD ["), std::string::npos) << health;
  EXPECT_EQ(CheckVislocCommand(ExecForm(health.substr(health.find("CMD [") + 4)), "HEALTHCHECK"),
            port);
}

// ---------------------------------------------------------------------------- compose

TEST(DeploymentConfigTest, ComposeRunsTheImageItBuildsWithRealFlagsPortsAndVolumes) {
  const std::string dir = kSource + "/docker";
  const YAML::Node compose = YAML::LoadFile(dir + "/compose.yaml");
  const YAML::Node server = compose["services"]["server"];
  ASSERT_TRUE(server) << "compose has no 'server' service";
  const std::string context = dir + "/" + server["build"]["context"].as<std::string>();
  EXPECT_TRUE(fs::exists(context + "/" + server["build"]["dockerfile"].as<std::string>()));
  const auto args = CheckServerArgs(Strings(server["command"]), "compose server command");
  const std::string port = PortOf(args.at("listen"));
  bool maps_mounted = false;
  for (const auto& volume : server["volumes"]) {
    const auto parts = Split(volume.as<std::string>(), ':');
    maps_mounted |= parts.size() >= 2 && parts[1] == args.at("maps") &&
                    compose["volumes"][parts[0]].IsDefined();
  }
  EXPECT_TRUE(maps_mounted) << "--maps " << args.at("maps") << " is not a named volume";
  // The healthcheck asks the HTTP side's /readyz (visloc health --http) on the --http port.
  ASSERT_TRUE(args.count("http")) << "the compose server has no --http";
  const std::string http_port = PortOf(args.at("http"));
  for (const auto& published : server["ports"]) {
    const std::string published_port = PortOf(published.as<std::string>());
    EXPECT_TRUE(published_port == port || published_port == http_port) << published_port;
  }
  const Command test = Strings(server["healthcheck"]["test"]);
  ASSERT_GE(test.size(), 2u);
  EXPECT_EQ(test[0], "CMD");
  EXPECT_EQ(
      CheckVislocCommand(Command(test.begin() + 1, test.end()), "compose healthcheck", "http"),
      http_port);

  // The demo client: the image's script, pointed at the server service and its port.
  const YAML::Node demo = compose["services"]["demo"];
  ASSERT_TRUE(demo) << "compose has no 'demo' service";
  EXPECT_EQ(demo["image"].as<std::string>(), server["image"].as<std::string>());
  const Command entry = Strings(demo["entrypoint"]);
  ASSERT_EQ(entry.size(), 2u);
  const std::string dockerfile = ReadFileBytes(dir + "/Dockerfile");
  EXPECT_NE(dockerfile.find("/usr/local/bin/" + entry[0]), std::string::npos)
      << entry[0] << " is not installed by the Dockerfile";
  EXPECT_EQ(entry[1], "server:" + port);
  EXPECT_EQ(demo["depends_on"]["server"]["condition"].as<std::string>(), "service_healthy");
}

// ---------------------------------------------------------------------------- Kubernetes

struct Manifests {
  std::vector<YAML::Node> documents;
  std::vector<YAML::Node> OfKind(const std::string& kind) const {
    std::vector<YAML::Node> found;
    for (const auto& doc : documents) {
      if (doc["kind"].as<std::string>() == kind) found.push_back(doc);
    }
    return found;
  }
  YAML::Node Named(const std::string& kind, const std::string& name) const {
    for (const auto& doc : OfKind(kind)) {
      if (doc["metadata"]["name"].as<std::string>() == name) return doc;
    }
    return YAML::Node();
  }
};

Manifests LoadKustomization(const std::string& dir, YAML::Node* kustomization) {
  *kustomization = YAML::LoadFile(dir + "/kustomization.yaml");
  Manifests manifests;
  for (const auto& resource : (*kustomization)["resources"]) {
    const std::string path = dir + "/" + resource.as<std::string>();
    EXPECT_TRUE(fs::exists(path)) << "kustomization names a missing " << path;
    if (!fs::exists(path)) continue;
    for (const auto& doc : YAML::LoadAllFromFile(path)) {
      if (doc.IsMap()) manifests.documents.push_back(doc);
    }
  }
  return manifests;
}

bool LabelsMatch(const YAML::Node& selector, const YAML::Node& labels) {
  for (const auto& entry : selector) {
    const YAML::Node value = labels[entry.first.as<std::string>()];
    if (!value || value.as<std::string>() != entry.second.as<std::string>()) return false;
  }
  return selector.size() > 0;
}

TEST(DeploymentConfigTest, KubernetesFleetHasOneWriterAndConsistentPortsMountsAndProbes) {
  YAML::Node kustomization;
  const Manifests k8s = LoadKustomization(kSource + "/deploy/k8s", &kustomization);
  const std::string image = kustomization["images"][0]["name"].as<std::string>();
  int writers = 0;
  const auto deployments = k8s.OfKind("Deployment");
  ASSERT_GE(deployments.size(), 2u);
  for (const auto& deployment : deployments) {
    const std::string name = deployment["metadata"]["name"].as<std::string>();
    const YAML::Node pod = deployment["spec"]["template"];
    EXPECT_TRUE(
        LabelsMatch(deployment["spec"]["selector"]["matchLabels"], pod["metadata"]["labels"]))
        << name << ": the selector does not select its own pods";
    EXPECT_TRUE(pod["spec"]["securityContext"]["runAsNonRoot"].as<bool>()) << name;
    for (const auto& volume : pod["spec"]["volumes"]) {
      if (volume["persistentVolumeClaim"]) {
        const std::string claim = volume["persistentVolumeClaim"]["claimName"].as<std::string>();
        EXPECT_TRUE(k8s.Named("PersistentVolumeClaim", claim)) << name << ": no claim " << claim;
      }
    }
    const YAML::Node container = pod["spec"]["containers"][0];
    EXPECT_EQ(container["image"].as<std::string>(), image) << name;
    const auto args = CheckServerArgs(Strings(container["args"]), name + " args");
    const std::string port = PortOf(args.at("listen"));
    EXPECT_EQ(container["ports"][0]["containerPort"].as<std::string>(), port) << name;
    std::map<std::string, bool> mounts;  // mountPath -> read-only
    for (const auto& mount : container["volumeMounts"]) {
      mounts[mount["mountPath"].as<std::string>()] =
          mount["readOnly"] && mount["readOnly"].as<bool>();
    }
    ASSERT_TRUE(mounts.count(args.at("maps"))) << name << ": --maps is not a mount";
    if (args.count("tokens")) {
      EXPECT_TRUE(mounts.count(fs::path(args.at("tokens")).parent_path().string()))
          << name << ": --tokens is not in a mount";
    }
    // A read-only replica mounts the maps read-only; the writer mounts them writable.
    const bool read_only = args.count("maps-read-only") > 0;
    EXPECT_EQ(mounts.at(args.at("maps")), read_only) << name;
    if (!read_only) {
      ++writers;
      EXPECT_EQ(deployment["spec"]["replicas"].as<int>(), 1) << name << " writes the maps";
      EXPECT_TRUE(deployment["spec"]["strategy"] &&
                  deployment["spec"]["strategy"]["type"].as<std::string>() == "Recreate")
          << name << " writes the maps: strategy Recreate, never two writers during a rollout";
    }
    // The probes ask the server's HTTP side (--http): readiness /readyz, liveness /healthz, on
    // the container port named http, which is the --http port.
    ASSERT_TRUE(args.count("http")) << name << ": no --http for the probes";
    ASSERT_EQ(container["ports"][1]["name"].as<std::string>(), "http") << name;
    EXPECT_EQ(container["ports"][1]["containerPort"].as<std::string>(), PortOf(args.at("http")))
        << name;
    for (const auto& [probe, path] :
         {std::pair<std::string, std::string>{"readinessProbe", "/readyz"},
          {"livenessProbe", "/healthz"}}) {
      ASSERT_TRUE(container[probe] && container[probe]["httpGet"]) << name << " has no " << probe;
      EXPECT_EQ(container[probe]["httpGet"]["path"].as<std::string>(), path) << name;
      EXPECT_EQ(container[probe]["httpGet"]["port"].as<std::string>(), "http") << name;
    }
  }
  EXPECT_EQ(writers, 1) << "uploads must go through exactly one server";

  // Every Service selects a Deployment's pods on its container port, and one is headless for
  // client-side balancing.
  bool headless = false;
  for (const auto& service : k8s.OfKind("Service")) {
    const std::string name = service["metadata"]["name"].as<std::string>();
    bool selects = false;
    for (const auto& deployment : deployments) {
      const YAML::Node pod = deployment["spec"]["template"];
      if (!LabelsMatch(service["spec"]["selector"], pod["metadata"]["labels"])) continue;
      selects = true;
      const YAML::Node port = pod["spec"]["containers"][0]["ports"][0];
      const std::string target = service["spec"]["ports"][0]["targetPort"].as<std::string>();
      EXPECT_TRUE(target == port["name"].as<std::string>() ||
                  target == port["containerPort"].as<std::string>())
          << name << ": targetPort " << target;
    }
    EXPECT_TRUE(selects) << "Service " << name << " selects no pods";
    headless |=
        service["spec"]["clusterIP"] && service["spec"]["clusterIP"].as<std::string>() == "None";
  }
  EXPECT_TRUE(headless) << "no headless Service for client-side balancing";
  for (const std::string kind : {"HorizontalPodAutoscaler"}) {
    for (const auto& doc : k8s.OfKind(kind)) {
      const std::string target = doc["spec"]["scaleTargetRef"]["name"].as<std::string>();
      EXPECT_TRUE(k8s.Named("Deployment", target)) << kind << " scales a missing " << target;
    }
  }
  for (const auto& budget : k8s.OfKind("PodDisruptionBudget")) {
    bool selects = false;
    for (const auto& deployment : deployments) {
      selects |= LabelsMatch(budget["spec"]["selector"]["matchLabels"],
                             deployment["spec"]["template"]["metadata"]["labels"]);
    }
    EXPECT_TRUE(selects) << "PodDisruptionBudget selects no pods";
  }
}

}  // namespace
}  // namespace visloc
