#include "treestereo/worker.hpp"

namespace treestereo {

Worker::Worker() : thread_([this] { loop(); }) {}

Worker::~Worker()
{
  {
    std::lock_guard<std::mutex> g(lock_);
    stop_ = true;
  }
  wake_.notify_one();
  thread_.join();
}

void Worker::post(std::function<void()> job)
{
  {
    std::lock_guard<std::mutex> g(lock_);
    jobs_.push_back(std::move(job));
  }
  wake_.notify_one();
}

void Worker::loop()
{
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock<std::mutex> g(lock_);
      wake_.wait(g, [this] { return stop_ || !jobs_.empty(); });
      if (jobs_.empty())
        return; // stopping, and nothing left to do
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    job(); // a packaged_task: exceptions go to its future
  }
}

} // namespace treestereo
