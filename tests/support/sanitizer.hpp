#pragma once
// NLID_TEST_ASAN is 1 in an AddressSanitizer build, 0 otherwise. g++ defines
// __SANITIZE_ADDRESS__; clang++ (what scripts/test uses) only answers __has_feature, so tests
// that shorten their records under the sanitizer must ask both.
#if defined(__SANITIZE_ADDRESS__)
#define NLID_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define NLID_TEST_ASAN 1
#endif
#endif
#ifndef NLID_TEST_ASAN
#define NLID_TEST_ASAN 0
#endif
