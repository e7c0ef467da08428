//! What a channel is ([`ChannelSpec`]), apart from the channels themselves so that the
//! layer's errors can name it.

/// What a channel is: the same for every port of one channel name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelSpec {
    /// Samples a subscriber buffers; when full, the oldest is dropped.
    pub depth: usize,
    /// Samples a subscriber that joins late still receives (0: none), at the latest together
    /// with the publisher's next sample (iceoryx2 hands them over when the publisher next
    /// looks at its connections).
    pub history: usize,
    /// Publishers the channel admits.
    pub publishers: usize,
    /// Subscribers the channel admits.
    pub subscribers: usize,
}
