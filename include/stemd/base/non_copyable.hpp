// Derive from NonCopyable for an object that owns a device, a thread or
// buffers others point into: copying it would share or double-free them.
// The interfaces of the backends derive from it, so no backend repeats it.
#pragma once

namespace stemd::base {

class NonCopyable {
public:
    NonCopyable(const NonCopyable&) = delete;
    NonCopyable& operator=(const NonCopyable&) = delete;

protected:
    NonCopyable() = default;
    ~NonCopyable() = default;
};

}  // namespace stemd::base
