#include "stipple/tiler/subtree_writer.hpp"

#include <algorithm>
#include <cstring>
#include <string>

#include <nlohmann/json.hpp>

namespace stipple::tiler {

std::vector<uint8_t> write_subtree(const std::vector<bool>& tiles, const std::vector<bool>& content,
                                   const std::vector<bool>& child_subtrees) {
  using nlohmann::json;
  std::vector<uint8_t> body;
  json views = json::array();
  auto availability = [&](const std::vector<bool>& bits) {
    const size_t count = size_t(std::count(bits.begin(), bits.end(), true));
    if (count == 0 || count == bits.size()) return json{{"constant", count ? 1 : 0}};
    const size_t at = body.size();
    body.resize(at + (bits.size() + 7) / 8, 0);
    for (size_t i = 0; i < bits.size(); ++i)
      if (bits[i]) body[at + i / 8] |= uint8_t(1u << (i % 8));
    views.push_back({{"buffer", 0}, {"byteOffset", at}, {"byteLength", body.size() - at}});
    body.resize((body.size() + 7) & ~size_t(7), 0);
    return json{{"bitstream", views.size() - 1}, {"availableCount", count}};
  };
  json j;
  j["tileAvailability"] = availability(tiles);
  j["contentAvailability"] = json::array({availability(content)});
  j["childSubtreeAvailability"] = availability(child_subtrees);
  if (!body.empty()) {
    j["buffers"] = json::array({{{"byteLength", body.size()}}});
    j["bufferViews"] = views;
  }
  std::string text = j.dump();
  text.resize((text.size() + 7) & ~size_t(7), ' ');
  const uint32_t magic = 0x74627573, version = 1;  // "subt"
  const uint64_t json_length = text.size(), body_length = body.size();
  std::vector<uint8_t> out(24 + text.size() + body.size());
  std::memcpy(out.data(), &magic, 4);
  std::memcpy(out.data() + 4, &version, 4);
  std::memcpy(out.data() + 8, &json_length, 8);
  std::memcpy(out.data() + 16, &body_length, 8);
  std::memcpy(out.data() + 24, text.data(), text.size());
  if (!body.empty()) std::memcpy(out.data() + 24 + text.size(), body.data(), body.size());
  return out;
}

}  // namespace stipple::tiler
