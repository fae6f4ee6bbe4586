#pragma once
// Whether the tests run under AddressSanitizer: its shadow memory and quarantine make a
// process's resident memory several times what the code itself holds, so assertions about
// peak RSS or a process memory budget do not hold there.
namespace stipple::test {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kAddressSanitizer = true;
#else
inline constexpr bool kAddressSanitizer = false;
#endif
#else
inline constexpr bool kAddressSanitizer = false;
#endif

}  // namespace stipple::test
