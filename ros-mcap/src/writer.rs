//! The MCAP writer: one [`LogFrame`] becomes one message on each topic
//! (`/diagnostics` on a change and once a second).

use crate::frames::{LogFrame, RosFrames};
use crate::msg;
use crate::{Geometry, LogError};
use std::collections::BTreeMap;
use std::io::{Seek, Write};

/// What a finished log holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LogStats {
    /// Frames written (messages on `/wmr/tracking`).
    pub frames: u64,
    /// Messages on `/diagnostics`.
    pub diagnostics: u64,
    /// Messages in the file, all topics.
    pub messages: u64,
}

/// An MCAP log being written.
pub struct McapLog<W: Write + Seek> {
    writer: mcap::Writer<W>,
    /// MCAP channel ids in the order of [`crate::CHANNELS`].
    ch: [u16; 5],
    frames: RosFrames,
    stats: LogStats,
    seq: u32,
}

impl McapLog<std::io::BufWriter<std::fs::File>> {
    /// A new log at `path` (`source` names who wrote it in the file's
    /// metadata: "wmr record", "hil-sim run").
    pub fn create(
        path: &std::path::Path,
        geometry: Geometry,
        source: &str,
    ) -> Result<Self, LogError> {
        let f = std::fs::File::create(path)
            .map_err(|e| LogError::Io(format!("cannot create {}: {e}", path.display())))?;
        Self::new(std::io::BufWriter::new(f), geometry, source)
    }
}

fn mcap_err(e: mcap::McapError) -> LogError {
    LogError::Mcap(e.to_string())
}

impl<W: Write + Seek> McapLog<W> {
    /// A log on `w`: the schemas, channels and a `wmr` metadata record
    /// (source, geometry, how time is mapped).
    pub fn new(w: W, geometry: Geometry, source: &str) -> Result<Self, LogError> {
        let opts = mcap::WriteOptions::new()
            .compression(None)
            .profile("ros2")
            .library(concat!("ros-mcap ", env!("CARGO_PKG_VERSION")));
        let mut writer = opts.create(w).map_err(mcap_err)?;
        let mut channel = |topic: &str, ty: &str| -> Result<u16, LogError> {
            let schema = writer
                .add_schema(ty, "ros2msg", msg::schema(ty).as_bytes())
                .map_err(mcap_err)?;
            writer
                .add_channel(schema, topic, "cdr", &BTreeMap::new())
                .map_err(mcap_err)
        };
        let mut ch = [0u16; 5];
        for (id, (topic, ty)) in ch.iter_mut().zip(crate::CHANNELS) {
            *id = channel(topic, ty)?;
        }
        let meta = BTreeMap::from([
            ("source".to_string(), source.to_string()),
            (
                "wheel_radius_m".to_string(),
                geometry.wheel_radius_m.to_string(),
            ),
            ("half_track_m".to_string(), geometry.half_track_m.to_string()),
            ("com_offset_m".to_string(), geometry.com_offset_m.to_string()),
            (
                "time".to_string(),
                "stamps are host Unix time: robot time plus the clock offset measured at the start (simulation: wall clock at the start plus simulated time)".to_string(),
            ),
            (
                "base_link".to_string(),
                "axle midpoint = G - d (cos theta, sin theta); /wmr/tracking poses are of G".to_string(),
            ),
        ]);
        writer
            .write_metadata(&mcap::records::Metadata {
                name: "wmr".into(),
                metadata: meta,
            })
            .map_err(mcap_err)?;
        Ok(Self {
            writer,
            ch,
            frames: RosFrames::new(geometry),
            stats: LogStats::default(),
            seq: 0,
        })
    }

    fn put(&mut self, channel: u16, stamp_ns: u64, data: &[u8]) -> Result<(), LogError> {
        self.writer
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: channel,
                    sequence: self.seq,
                    log_time: stamp_ns,
                    publish_time: stamp_ns,
                },
                data,
            )
            .map_err(mcap_err)?;
        self.stats.messages += 1;
        Ok(())
    }

    /// Writes one frame on every topic (`/diagnostics` when due).
    pub fn write(&mut self, f: &LogFrame) -> Result<(), LogError> {
        self.seq = self.seq.wrapping_add(1);
        for (i, data) in self.frames.messages(f).encoded()? {
            self.put(self.ch[i], f.stamp_ns, &data)?;
            if i == 4 {
                self.stats.diagnostics += 1;
            }
        }
        self.stats.frames += 1;
        Ok(())
    }

    /// Writes the summary and index and flushes the file.
    pub fn finish(mut self) -> Result<LogStats, LogError> {
        self.writer.finish().map_err(mcap_err)?;
        Ok(self.stats)
    }
}
