// The viewer's input-script parser (scripted input for the windowed tests).
#include <gtest/gtest.h>

#include "stipple/core/error.hpp"
#include "stipple/viewer/script.hpp"

using namespace stipple;
using namespace stipple::viewer;

TEST(Script, ParsesEventsInFrameOrder) {
  const InputScript s = parse_input_script(
      R"({"events": [{"frame": 5, "click": "left"}, {"frame": 2, "move": [10.5, 20]},
                     {"frame": 3, "tap": "2"}, {"frame": 4, "scroll": [0, -1]},
                     {"frame": 6, "press": "enter"}, {"frame": 7, "release": "B"}], "exit": 9})",
      "s.json");
  EXPECT_EQ(s.exit_frame, 9u);
  ASSERT_EQ(s.events.size(), 8u);
  EXPECT_EQ(s.events[0].frame, 2u);
  EXPECT_EQ(s.events[0].event.type, platform::InputEvent::Type::CursorMove);
  EXPECT_EQ(s.events[0].event.value, glm::dvec2(10.5, 20));
  EXPECT_EQ(s.events[1].event.code, int(platform::Key::Num2));
  EXPECT_TRUE(s.events[1].event.down);
  EXPECT_FALSE(s.events[2].event.down);
  EXPECT_EQ(s.events[7].event.code, int(platform::Key::B));
  for (const char* bad :
       {"[1, 2]", R"({"events": [{"frame": 1}]})", R"({"events": [{"frame": -1, "tap": "a"}]})",
        R"({"events": [{"frame": 1, "tap": "hyperspace"}]})",
        R"({"events": [{"frame": 1, "move": [1]}]})", "{\"events\": "})
    EXPECT_THROW(parse_input_script(bad, "bad.json"), Error) << bad;
}
