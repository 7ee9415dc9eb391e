// The mapping job registry behind ListJobs (`visloc jobs`): frames, counts and pose from each
// frame's answer, the count after MappingEnd, and only the newest ended jobs kept (running ones
// never dropped).

#include <gtest/gtest.h>

#include "server/mapping_service.h"

namespace visloc::server {
namespace {

v1::MappingProgress Answer(v1::MappingState state, uint64_t index, uint32_t keyframes) {
  v1::MappingProgress progress;
  progress.set_state(state);
  progress.set_frame_index(index);
  progress.set_keyframes(keyframes);
  progress.set_points(100 * keyframes);
  return progress;
}

TEST(MappingJobsTest, FramesAndCountsFollowTheAnswers) {
  MappingJobs jobs;
  const uint64_t id = jobs.Begin("hall", "robot-1");
  jobs.Update(id, Answer(v1::MAPPING_TRACKING, 0, 1));
  jobs.Update(id, Answer(v1::MAPPING_TRACKING, 1, 2));
  jobs.Update(id, Answer(v1::MAPPING_FRAME_ERROR, 2, 0));  // A bad frame keeps the counts.
  std::vector<v1::MappingJob> now = jobs.Snapshot();
  ASSERT_EQ(now.size(), 1u);
  EXPECT_EQ(now[0].frames(), 3u);
  EXPECT_EQ(now[0].keyframes(), 2u);
  EXPECT_EQ(now[0].points(), 200u);
  EXPECT_EQ(now[0].state(), v1::MAPPING_FRAME_ERROR);
  EXPECT_EQ(now[0].ended_unix_ns(), 0);
  jobs.Update(id, Answer(v1::MAPPING_PUBLISHED, 3, 2));  // After MappingEnd: the count.
  jobs.End(id, v1::MAPPING_PUBLISHED, "");
  now = jobs.Snapshot();
  EXPECT_EQ(now[0].frames(), 3u);
  EXPECT_EQ(now[0].state(), v1::MAPPING_PUBLISHED);
  EXPECT_GE(now[0].ended_unix_ns(), now[0].started_unix_ns());
  EXPECT_TRUE(jobs.Ended(id));
}

TEST(MappingJobsTest, OnlyTheNewestEndedJobsAreKeptAndRunningOnesStay) {
  MappingJobs jobs(2);
  const uint64_t running = jobs.Begin("long", "");
  for (int i = 0; i < 5; ++i) {
    const uint64_t id = jobs.Begin("map" + std::to_string(i), "");
    jobs.End(id, v1::MAPPING_ABANDONED, "cut");
  }
  const std::vector<v1::MappingJob> now = jobs.Snapshot();
  ASSERT_EQ(now.size(), 3u);
  EXPECT_EQ(now[0].job_id(), running);
  EXPECT_EQ(now[1].map_name(), "map3");
  EXPECT_EQ(now[2].map_name(), "map4");
  EXPECT_FALSE(jobs.Ended(running));
}

// A restarted server's registry: the spool's jobs under their own ids, with what happened to
// them, and new jobs numbered after every id handed out before.
TEST(MappingJobsTest, AdoptedJobsKeepTheirIdsAndNewOnesFollow) {
  MappingJobs jobs;
  jobs.IdsAfter(7);
  jobs.Adopt(4, "hall", "robot-1", "its server stopped after 120 frames");
  EXPECT_EQ(jobs.Begin("yard", ""), 8u);
  jobs.Adopt(11, "dock", "", "");
  EXPECT_EQ(jobs.Begin("roof", ""), 12u);
  const std::vector<v1::MappingJob> now = jobs.Snapshot();
  ASSERT_EQ(now.size(), 4u);
  EXPECT_EQ(now[0].job_id(), 4u);
  EXPECT_EQ(now[0].state(), v1::MAPPING_WAITING);
  EXPECT_EQ(now[0].note(), "its server stopped after 120 frames");
  EXPECT_FALSE(jobs.Ended(4));
}

}  // namespace
}  // namespace visloc::server
