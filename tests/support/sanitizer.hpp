// Whether the tests were built with AddressSanitizer (`make sanitize`). Such a build runs several
// times slower (10x for a live run's augmenter), so the tests that run augrig in real time against
// the wall clock wait kSlowdown times longer for what they count; what they check of the content
// stays the same.
#pragma once

namespace augrig::test {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif
#else
inline constexpr bool kSanitized = false;
#endif
inline constexpr int kSlowdown = kSanitized ? 4 : 1;

}  // namespace augrig::test
