// Byte-for-byte comparison of generated images: the generators promise the
// same bytes for the same options.
#pragma once

#include <cstring>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace stemd::test {

inline bool same_bytes(const cv::Mat& a, const cv::Mat& b)
{
    if (a.size() != b.size() || a.type() != b.type() || !a.isContinuous() || !b.isContinuous())
        return false;
    return std::memcmp(a.data, b.data, a.total() * a.elemSize()) == 0;
}

// The BGR, NIR and mask planes of two generated frames (or strips) are the same bytes.
template <typename Images>
void expect_same_planes(const Images& a, const Images& b)
{
    EXPECT_TRUE(same_bytes(a.bgr, b.bgr));
    EXPECT_TRUE(same_bytes(a.nir, b.nir));
    EXPECT_TRUE(same_bytes(a.mask, b.mask));
}

}  // namespace stemd::test
