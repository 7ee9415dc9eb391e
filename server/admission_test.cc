#include "server/admission.h"

#include <gtest/gtest.h>

#include "core/util/args.h"
#include "server/work_permits.h"
#include "server/worker_load.h"

namespace visloc::server {
namespace {

using Clock = WorkerLoad::Clock;
using std::chrono::milliseconds;
using std::chrono::seconds;

// 30 frames a second for 10 s, each 40 ms of work after `wait` in the queue.
void Load(Clock::time_point start, milliseconds wait, WorkerLoad* load) {
  for (int i = 0; i < 300; ++i) {
    const Clock::time_point at = start + milliseconds(i * 1000 / 30);
    load->AddWait(at, wait);
    load->AddBusy(at + milliseconds(40), milliseconds(40));
  }
}

TEST(WorkerLoadTest, BusyFractionFramesAndWaitsOverTheWindow) {
  const Clock::time_point start = Clock::now();
  WorkerLoad load(2, seconds(10), start);
  Load(start, milliseconds(3), &load);
  // At 10 s the window is seconds 1 to 9 (the ring's slot of second 0 now holds second 10's
  // first work, and second 10 has only begun).
  const WorkerLoadStats at_end = load.Over(start + seconds(10));
  EXPECT_NEAR(at_end.window_s, 9.0, 1e-6);
  EXPECT_NEAR(at_end.busy_fraction, 0.6, 0.01);  // 30 x 40 ms a second over 2 workers.
  EXPECT_NEAR(at_end.frames_per_s, 30.0, 0.5);
  EXPECT_EQ(at_end.wait_p95_ms, 3.2);  // The bucket 1.6 to 3.2 ms.
  // Half-way through the start-up, the figures cover what has passed.
  const WorkerLoadStats early = load.Over(start + seconds(5));
  EXPECT_NEAR(early.window_s, 5.0, 1e-6);
  // Twenty seconds later, nothing is left in the window.
  const WorkerLoadStats later = load.Over(start + seconds(30));
  EXPECT_EQ(later.frames, 0);
  EXPECT_EQ(later.busy_fraction, 0.0);
}

double fake_cpu_s = 0.0;
double FakeCpuSeconds() { return fake_cpu_s; }

TEST(WorkerLoadTest, TheProcesssCoresOverTheLastSeconds) {
  const Clock::time_point start = Clock::now();
  WorkerLoad load(2, seconds(10), start, &FakeCpuSeconds);
  for (int s = 0; s < 10; ++s) {
    fake_cpu_s = 1.5 * s;  // 1.5 cores.
    load.AddWait(start + seconds(s), milliseconds(0));
  }
  fake_cpu_s = 1.5 * 9.5;
  EXPECT_NEAR(load.Over(start + milliseconds(9500)).process_cpu_cores, 1.5, 1e-9);
}

TEST(WorkerLoadTest, ScopedPermitsAccountTheirWaitAndWork) {
  WorkPermits permits(1);
  {
    const WorkPermit permit(&permits);
    const SparePermits none(&permits, 1);  // The only permit is taken: no spare.
    EXPECT_EQ(none.taken(), 0);
  }
  const WorkerLoadStats stats = permits.load().Over(Clock::now());
  EXPECT_EQ(stats.frames, 1);
  EXPECT_GE(stats.busy_fraction, 0.0);
}

// Sessions of 20 Hz frames of 3.6 ms each (752x480 JPEG on this machine's cores): 0.072 cores
// apiece; `measured` of them there for a minute, `unmeasured` just arrived.
std::vector<SessionLoad> Sessions(int measured, int unmeasured) {
  std::vector<SessionLoad> sessions(measured, SessionLoad{0.072, 60.0});
  sessions.insert(sessions.end(), unmeasured, SessionLoad{-1.0, 0.1});
  return sessions;
}

WorkerLoadStats Window(double busy_fraction) {
  WorkerLoadStats load;
  load.window_s = 10;
  load.frames = 6000;
  load.busy_fraction = busy_fraction;
  load.wait_p95_ms = 1.6;
  return load;
}

TEST(AdmissionTest, ARobotIsRefusedWhenItsShareWouldTakeTheWorkersPastTheLimit) {
  const AdmissionOptions options;
  // 20 sessions: 72% of two workers; one more makes 75.6%.
  const AdmissionDecision at_20 = DecideAdmission(Window(0.72), 2, Sessions(20, 0), options);
  EXPECT_TRUE(at_20.admit) << at_20.why;
  EXPECT_NEAR(at_20.projected_busy_fraction, 0.756, 1e-9);
  const AdmissionDecision at_22 = DecideAdmission(Window(0.79), 2, Sessions(22, 0), options);
  EXPECT_FALSE(at_22.admit);
  EXPECT_EQ(at_22.why,
            "server at capacity: its workers (2) were 79% busy over the last 10 s with 22 "
            "sessions (22.0 of them over that time), the process used 0.00 cores (0.072 a "
            "session); frames waited 1.6 ms for a worker (p95); one more session would take them "
            "to 83%, over the 80% that keeps its robots on time. Retry in a few seconds, or on "
            "another replica");
  // Off: only --max-sessions limits.
  AdmissionOptions off;
  off.max_busy_fraction = 0.0;
  EXPECT_TRUE(DecideAdmission(Window(0.79), 2, Sessions(22, 0), off).admit);
}

// A group of robots arriving at once: the window has not seen the first of them yet when the
// last asks, but each counts at the median session's cost.
TEST(AdmissionTest, RobotsArrivingTogetherCountBeforeTheirFramesAreMeasured) {
  const AdmissionOptions options;
  int admitted = 0;
  for (int newcomer = 0; newcomer < 16; ++newcomer) {
    const AdmissionDecision d = DecideAdmission(Window(0.72), 2, Sessions(20, admitted), options);
    admitted += d.admit;
  }
  EXPECT_EQ(admitted, 2);  // 20 + 2 sessions: 79.2%; a 23rd would make 82.8%.
}

// Refused robots retrying a second apart: each is measured within a second (its CPU time, half
// its wall time on a contended machine), long before the window has seen it whole. Bug: the
// window's lagging busy fraction plus CPU-costed newcomers let in 7 robots past the limit
// (docs/admission.md's run at 551e3d8: 19 sessions, then 26 and a p99 of 77 ms).
TEST(AdmissionTest, RobotsRetryingOneBehindAnotherAreCountedWholeBeforeTheWindowSeesThem) {
  const double wall_per_session = 0.72 / 19;  // The window's busy fraction a session.
  std::vector<SessionLoad> sessions(19, SessionLoad{0.057, 60.0});
  for (int second = 0; second < 20; ++second) {
    double in_window = 0.0;
    for (SessionLoad& s : sessions) {
      s.age_s += 1.0;
      in_window += std::min(1.0, s.age_s / 10.0);
    }
    const AdmissionDecision d =
        DecideAdmission(Window(wall_per_session * in_window), 2, sessions, {});
    if (d.admit) sessions.push_back({0.057, 0.0});
  }
  EXPECT_EQ(sessions.size(), 21u);  // 0.0379 x 22 = 0.83 is over 0.8.
}

// The window also sees what the sessions' own costs miss: the cores taken by something else.
TEST(AdmissionTest, TheWindowsLoadCountsWhenItExceedsTheSessionsOwn) {
  const AdmissionDecision d = DecideAdmission(Window(0.85), 2, Sessions(10, 0), {});
  EXPECT_FALSE(d.admit);
  EXPECT_NEAR(d.projected_busy_fraction, 0.85 * 11 / 10, 1e-9);
}

// The process spends more than its sessions' frames (the link's threads receive and parse each
// frame): each session, the newcomer too, costs its share of that.
TEST(AdmissionTest, TheProcesssOverheadIsSharedOverTheSessions) {
  WorkerLoadStats load = Window(0.3);
  load.process_cpu_cores = 1.152;  // Twice the 8 measured sessions' own 0.576 cores.
  const AdmissionDecision d = DecideAdmission(load, 2, Sessions(8, 4), {});
  // 12 sessions at 0.144 cores: 1.728 cores committed; one more makes 1.872, 94% of two.
  EXPECT_FALSE(d.admit);
  EXPECT_NEAR(d.projected_busy_fraction, (1.728 + 0.144) / 2, 1e-9);
  // A mapping job's core is not a robot's: the overhead counted is at most three times.
  load = Window(0.07);
  load.process_cpu_cores = 1.0 + 0.072 * 2;
  const AdmissionDecision with_mapping = DecideAdmission(load, 2, Sessions(2, 0), {});
  EXPECT_TRUE(with_mapping.admit) << with_mapping.why;
  EXPECT_NEAR(with_mapping.projected_busy_fraction, 1.144 / 2 + 0.216 / 2, 1e-9);
}

TEST(AdmissionTest, FramesAlreadyWaitingLongForAWorkerRefuseANewcomer) {
  WorkerLoadStats load = Window(0.3);
  load.wait_p95_ms = 25.6;  // A burst: the cores are shared with something else.
  const AdmissionDecision decision = DecideAdmission(load, 2, Sessions(5, 0), {});
  EXPECT_FALSE(decision.admit);
  EXPECT_NE(decision.why.find("over the 20.0 ms wait it allows"), std::string::npos)
      << decision.why;
}

TEST(AdmissionTest, WithNothingMeasuredYetARobotIsAdmitted) {
  WorkerLoadStats load;
  load.window_s = 1;
  load.frames = 20;
  load.busy_fraction = 0.95;  // A first robot's map load and first frames.
  EXPECT_TRUE(DecideAdmission(load, 2, Sessions(0, 1), {}).admit);
  EXPECT_TRUE(DecideAdmission(WorkerLoadStats{}, 2, {}, {}).admit);
}

TEST(AdmissionTest, OptionsOutOfRangeAreNamed) {
  AdmissionOptions options;
  options.max_busy_fraction = 1.5;
  EXPECT_THROW(options.Check(), UsageError);
  options.max_busy_fraction = 0.8;
  options.max_wait_p95_ms = 0.0;
  EXPECT_THROW(options.Check(), UsageError);
}

}  // namespace
}  // namespace visloc::server
