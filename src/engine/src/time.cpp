#include "stipple/engine/time.hpp"

#include "stipple/engine/engine.hpp"

namespace stipple {

void advance_time(Registry& main) {
  Time& time = main.resource<Time>();
  auto now = std::chrono::steady_clock::now();
  bool first = time.last == std::chrono::steady_clock::time_point{};
  if (!first) ++time.frame;
  time.delta_seconds = time.fixed_delta > 0
                           ? (first ? 0.0 : time.fixed_delta)
                           : (first ? 0.0 : std::chrono::duration<double>(now - time.last).count());
  time.elapsed_seconds += time.delta_seconds;
  time.last = now;
}

void extract_time(Registry& main) {
  const Time& time = main.resource<Time>();
  main.resource<RenderWorldRef>()->insert_resource(
      RenderTime{time.frame, time.delta_seconds, time.elapsed_seconds});
}

void TimePlugin::build(Engine& engine) {
  Time time;
  time.fixed_delta = fixed_delta;
  engine.main().insert_resource(time);
  engine.render().insert_resource(RenderTime{});
  engine.add_system(MainStage::Input, advance_time, "advance_time");
  engine.add_system(MainStage::Extract, extract_time, "extract_time");
}

}  // namespace stipple
