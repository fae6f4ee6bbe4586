#include "stipple/io/subtree.hpp"

#include <cstring>

#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"

namespace stipple::io {

using json = nlohmann::json;

uint64_t subtree_tile_count(int branching, int levels) {
  uint64_t total = 0, level_count = 1;
  for (int l = 0; l < levels; ++l, level_count *= uint64_t(branching)) total += level_count;
  return total;
}

uint64_t availability_index(int branching, int level, uint64_t morton) {
  return subtree_tile_count(branching, level) + morton;
}

uint64_t morton_index(uint32_t x, uint32_t y, uint32_t z, int branching) {
  uint64_t m = 0;
  const int dims = branching == 8 ? 3 : 2;
  for (int bit = 0; bit < 21; ++bit) {
    m |= uint64_t((x >> bit) & 1) << (bit * dims);
    m |= uint64_t((y >> bit) & 1) << (bit * dims + 1);
    if (dims == 3) m |= uint64_t((z >> bit) & 1) << (bit * dims + 2);
  }
  return m;
}

// JSON accessors throw nlohmann exceptions on a wrong type; the public entry point below turns
// them into stipple::Error naming the file.
static Subtree decode_subtree_unchecked(std::span<const uint8_t> data, const std::string& name,
                                        int branching, int levels, const BufferResolver& resolver) {
  if (branching != 4 && branching != 8) fail("{}: branching factor must be 4 or 8", name);
  // A subtree's bitstreams grow as N^levels; refuse what could not be held.
  if (levels < 1 || (branching == 8 ? levels > 10 : levels > 15))
    fail("{}: subtreeLevels {} is out of the supported range", name, levels);
  json j;
  std::span<const uint8_t> bin;
  if (data.size() >= 4 && std::memcmp(data.data(), "subt", 4) == 0) {
    if (data.size() < 24) fail("{}: too short for a subtree header", name);
    uint32_t version = detail::read_u32(data, 4);
    if (version != 1) fail("{}: subtree version {} is not supported", name, version);
    uint64_t json_length = detail::read_u64(data, 8), bin_length = detail::read_u64(data, 16);
    if (json_length > data.size() - 24 || bin_length > data.size() - 24 - json_length)
      fail("{}: subtree JSON ({} bytes) and binary ({} bytes) exceed the file's {} bytes", name,
           json_length, bin_length, data.size());
    auto text = data.subspan(24, json_length);
    size_t n = text.size();
    while (n > 0 && (text[n - 1] == ' ' || text[n - 1] == 0)) --n;
    j = json::parse(text.begin(), text.begin() + std::ptrdiff_t(n), nullptr, false);
    bin = data.subspan(24 + json_length, bin_length);
  } else {
    j = json::parse(data.begin(), data.end(), nullptr, false);
  }
  if (j.is_discarded() || !j.is_object()) fail("{}: subtree JSON is not valid", name);

  std::vector<std::vector<uint8_t>> owned;
  std::vector<std::span<const uint8_t>> buffers;
  const json buffer_list = j.value("buffers", json::array());
  owned.reserve(buffer_list.size());
  for (size_t i = 0; i < buffer_list.size(); ++i) {
    const json& b = buffer_list[i];
    if (!b.is_object()) fail("{}: buffer {} is not an object", name, i);
    uint64_t length = b.value("byteLength", uint64_t(0));
    std::span<const uint8_t> bytes;
    if (b.contains("uri")) {
      if (!resolver || !b["uri"].is_string())
        fail("{}: buffer {} refers to an external file that cannot be fetched here", name, i);
      owned.push_back(resolver(b["uri"].get<std::string>()));
      bytes = owned.back();
    } else {
      bytes = bin;
    }
    if (bytes.size() < length)
      fail("{}: buffer {} holds {} bytes, byteLength says {}", name, i, bytes.size(), length);
    buffers.push_back(bytes.first(length));
  }
  std::vector<std::span<const uint8_t>> views;
  for (const auto& v : j.value("bufferViews", json::array())) {
    if (!v.is_object()) fail("{}: a bufferView is not an object", name);
    int64_t b = v.value("buffer", int64_t(-1));
    uint64_t offset = v.value("byteOffset", uint64_t(0)),
             length = v.value("byteLength", uint64_t(0));
    if (b < 0 || uint64_t(b) >= buffers.size())
      fail("{}: bufferView refers to buffer {} of {}", name, b, buffers.size());
    if (offset > buffers[b].size() || buffers[b].size() - offset < length)
      fail("{}: bufferView ({} bytes at {}) lies outside buffer {} ({} bytes)", name, length,
           offset, b, buffers[b].size());
    views.push_back(buffers[b].subspan(offset, length));
  }

  auto availability = [&](const json& a, uint64_t bits, const char* what) {
    Availability out;
    if (!a.is_object()) fail("{}: {} is not an object", name, what);
    if (a.contains("constant")) {
      out.constant = true;
      out.value = a["constant"].is_number() && a["constant"].get<double>() != 0;
      return out;
    }
    // "bitstream" in 1.1, "bufferView" in the 1.0 extension.
    const json* view = a.contains("bitstream")    ? &a["bitstream"]
                       : a.contains("bufferView") ? &a["bufferView"]
                                                  : nullptr;
    if (!view || !view->is_number_integer() || view->get<int64_t>() < 0 ||
        view->get<uint64_t>() >= views.size())
      fail("{}: {} has neither a constant nor a valid bitstream", name, what);
    auto bytes = views[view->get<size_t>()];
    if (bytes.size() < (bits + 7) / 8)
      fail("{}: {} bitstream holds {} bytes, {} bits need {}", name, what, bytes.size(), bits,
           (bits + 7) / 8);
    out.constant = false;
    out.bit_count = bits;
    out.bits.assign(bytes.begin(), bytes.begin() + std::ptrdiff_t((bits + 7) / 8));
    return out;
  };
  const uint64_t tile_bits = subtree_tile_count(branching, levels);
  uint64_t child_bits = 1;
  for (int l = 0; l < levels; ++l) child_bits *= uint64_t(branching);

  Subtree s;
  if (!j.contains("tileAvailability")) fail("{}: subtree has no tileAvailability", name);
  s.tiles = availability(j["tileAvailability"], tile_bits, "tileAvailability");
  if (auto it = j.find("contentAvailability"); it != j.end()) {
    if (it->is_array()) {
      for (const auto& a : *it)
        s.contents.push_back(availability(a, tile_bits, "contentAvailability"));
    } else {
      s.contents.push_back(availability(*it, tile_bits, "contentAvailability"));
    }
  }
  if (!j.contains("childSubtreeAvailability"))
    fail("{}: subtree has no childSubtreeAvailability", name);
  s.child_subtrees =
      availability(j["childSubtreeAvailability"], child_bits, "childSubtreeAvailability");
  return s;
}

Subtree decode_subtree(std::span<const uint8_t> data, const std::string& name, int branching,
                       int levels, const BufferResolver& resolver) {
  try {
    return decode_subtree_unchecked(data, name, branching, levels, resolver);
  } catch (const nlohmann::json::exception& e) {
    fail("{}: malformed JSON: {}", name, e.what());
  }
}

}  // namespace stipple::io
