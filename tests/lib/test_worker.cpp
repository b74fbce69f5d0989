#include "treestereo/worker.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <malloc.h>
#ifdef __SANITIZE_ADDRESS__
// libasan's (gcc ships no header for it): bytes allocated and not yet freed.
extern "C" size_t __sanitizer_get_current_allocated_bytes();
#endif

#include <stdexcept>
#include <vector>

using namespace treestereo;

TEST(Worker, RunsJobsInOrderOnOneThread)
{
  Worker w;
  std::vector<int> order;
  std::vector<std::future<std::thread::id>> ids;
  for (int i = 0; i < 50; i++)
    ids.push_back(w.run([&order, i] {
      order.push_back(i); // only the worker touches it, one job at a time
      return std::this_thread::get_id();
    }));
  for (auto &f : ids) {
    const std::thread::id id = f.get();
    EXPECT_EQ(id, w.id());
    EXPECT_NE(id, std::this_thread::get_id());
  }
  ASSERT_EQ(order.size(), 50u);
  for (int i = 0; i < 50; i++)
    EXPECT_EQ(order[size_t(i)], i);
}

TEST(Worker, ReturnsValuesAndExceptions)
{
  Worker w;
  EXPECT_EQ(w.run([] { return 6 * 7; }).get(), 42);
  auto bad = w.run([]() -> int { throw std::runtime_error("no such view"); });
  EXPECT_THROW(bad.get(), std::runtime_error);
  EXPECT_EQ(w.run([] { return 1; }).get(), 1); // still working after a throw
}

TEST(Worker, DestructorFinishesQueuedJobs)
{
  int done = 0;
  {
    Worker w;
    for (int i = 0; i < 20; i++)
      w.run([&done] { done++; });
  }
  EXPECT_EQ(done, 20);
}

// The reason the worker exists: OpenCV work on a fresh thread per call keeps growing the heap
// (OpenCV holds on to the thread-local data of finished threads); on one worker it does not.
TEST(Worker, OpenCvOnTheWorkerDoesNotGrowTheHeap)
{
  cv::Mat img(120, 160, CV_8U), out;
  cv::randu(img, 0, 255);
  auto blur = [&] { cv::GaussianBlur(img, out, cv::Size(5, 5), 1.5); };
  auto in_use = [] {
#ifdef __SANITIZE_ADDRESS__
    return double(__sanitizer_get_current_allocated_bytes()); // ASan's malloc, not glibc's
#else
    const struct mallinfo2 m = mallinfo2();
    return double(m.uordblks + m.hblkhd);
#endif
  };
  Worker w;
  for (int i = 0; i < 20; i++) // warm-up: OpenCV's one-time allocations
    w.run(blur).get();
  const double before = in_use();
  for (int i = 0; i < 300; i++)
    w.run(blur).get();
  const double worker_growth = in_use() - before;

  const double before_async = in_use();
  for (int i = 0; i < 300; i++)
    std::async(std::launch::async, blur).get();
  const double async_growth = in_use() - before_async;
  // 300 calls: the worker stays within a few kB; a thread per call keeps >= 100 B for each.
  EXPECT_LT(worker_growth, 8 * 1024.0) << "async grew " << async_growth;
  EXPECT_GT(async_growth, 300 * 100.0) << "this OpenCV no longer keeps dead threads' data";
}
