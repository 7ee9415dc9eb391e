#pragma once
// The `visloc` subcommands. Each RunX parses and validates its arguments, calls the library
// that does the work, prints results (human-readable, or JSON with --json) and returns the
// process exit code. Failures print one line "visloc X: reason" to stderr and return non-zero.

#include <string>
#include <vector>

namespace visloc::cli {

using Args = std::vector<std::string>;

int RunSim(const Args& args);
int RunEval(const Args& args);
int RunMap(const Args& args);
int RunMapMerge(const Args& args);   // `visloc map merge`
int RunMapExtend(const Args& args);  // `visloc map extend`
int RunMapUpdate(const Args& args);  // `visloc map update`
int RunMapAlign(const Args& args);   // `visloc map align`
int RunMapLocalizability(const Args& args);  // `visloc map localizability`
int RunDataset(const Args& args);
int RunDatasetImport(const Args& args);  // `visloc dataset import`
int RunCalibrate(const Args& args);
int RunLocalize(const Args& args);
int RunStream(const Args& args);
int RunRelocalize(const Args& args);
int RunPlot(const Args& args);
int RunBench(const Args& args);
int RunHealth(const Args& args);
int RunSessions(const Args& args);  // `visloc sessions`
int RunJobs(const Args& args);      // `visloc jobs`
int RunLoad(const Args& args);      // `visloc load`

// True when stderr is a terminal, so progress lines with carriage returns make sense.
bool ShowProgress();

}  // namespace visloc::cli
