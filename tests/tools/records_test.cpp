// The inspect tool's decoding of a record's extra bytes by their descriptors (LAS 1.4 R15,
// section 2.5 of the extra bytes VLR): typed scalars, scale and offset where the options say
// so, two- and three-component types, undocumented bytes as hex, and bytes no descriptor covers.
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <variant>
#include <vector>

#include "stipple/tools/records.hpp"

using namespace stipple;

namespace {

io::ExtraBytesDescriptor descriptor(const std::string& name, uint8_t type, size_t size,
                                    uint8_t options = 0) {
  io::ExtraBytesDescriptor d;
  d.name = name;
  d.data_type = type;
  d.size = size;
  d.options = options;
  return d;
}

template <typename T>
void put(std::vector<uint8_t>& bytes, T value) {
  uint8_t raw[sizeof(T)];
  std::memcpy(raw, &value, sizeof(T));  // little endian, as LAS stores it
  bytes.insert(bytes.end(), raw, raw + sizeof(T));
}

double number(const io::GeoValue& v) {
  return std::get<double>(v);
}

}  // namespace

TEST(Records, ExtraBytesDecodeByTheirDescriptors) {
  std::vector<io::ExtraBytesDescriptor> ds;
  ds.push_back(descriptor("amplitude", 3, 2, 8 | 16));  // u16, scaled and offset
  ds.back().scale[0] = 0.5;
  ds.back().offset[0] = 10.0;
  ds.push_back(descriptor("signed", 6, 4, 16));  // i32, offset only
  ds.back().scale[0] = 100.0;                    // ignored: bit 3 not set
  ds.back().offset[0] = -0.25;
  ds.push_back(descriptor("range", 10, 8));    // f64
  ds.push_back(descriptor("pad", 0, 2));       // undocumented: shown as bytes
  ds.push_back(descriptor("pair", 13, 4, 8));  // two u16 (deprecated array type), scaled each
  ds.back().scale[0] = 1.0;
  ds.back().scale[1] = 0.125;
  ds.push_back(descriptor("tilt", 9, 4));  // f32

  std::vector<uint8_t> bytes;
  put<uint16_t>(bytes, 300);
  put<int32_t>(bytes, -7);
  put<double>(bytes, 1234.5625);
  bytes.push_back(0xbe), bytes.push_back(0xef);
  put<uint16_t>(bytes, 65535);
  put<uint16_t>(bytes, 12);
  put<float>(bytes, -1.5f);
  bytes.push_back(0x01), bytes.push_back(0xa0), bytes.push_back(0xff);  // no descriptor

  const auto fields = tools::decode_extra_bytes(ds, bytes.data(), bytes.size());
  ASSERT_EQ(fields.size(), 7u);
  EXPECT_EQ(fields[0].first, "amplitude");
  EXPECT_EQ(number(fields[0].second), 300 * 0.5 + 10.0);
  EXPECT_EQ(fields[1].first, "signed");
  EXPECT_EQ(number(fields[1].second), -7.25);
  EXPECT_EQ(number(fields[2].second), 1234.5625);
  EXPECT_EQ(fields[3].first, "pad");
  EXPECT_EQ(std::get<std::string>(fields[3].second), "beef");
  EXPECT_EQ(fields[4].first, "pair");
  EXPECT_EQ(std::get<std::vector<double>>(fields[4].second), (std::vector<double>{65535, 1.5}));
  EXPECT_EQ(number(fields[5].second), -1.5);
  EXPECT_EQ(fields[6].first, "extra_bytes");
  EXPECT_EQ(std::get<std::string>(fields[6].second), "01a0ff");
}

// A record shorter than its descriptors say (a file whose VLR and point size disagree): the
// attributes that fit are decoded, the rest shown as bytes, nothing read past the record.
TEST(Records, ExtraBytesShorterThanTheDescriptors) {
  const std::vector<io::ExtraBytesDescriptor> ds = {descriptor("a", 3, 2), descriptor("b", 10, 8)};
  std::vector<uint8_t> bytes;
  put<uint16_t>(bytes, 513);
  bytes.push_back(0x7f), bytes.push_back(0x00), bytes.push_back(0x10);
  const auto fields = tools::decode_extra_bytes(ds, bytes.data(), bytes.size());
  ASSERT_EQ(fields.size(), 2u);
  EXPECT_EQ(number(fields[0].second), 513.0);
  EXPECT_EQ(fields[1].first, "extra_bytes");
  EXPECT_EQ(std::get<std::string>(fields[1].second), "7f0010");
}
