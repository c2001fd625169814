//! sqlite3 storage files (rosbag2's default on Humble), read with rusqlite from the `topics` and
//! `messages` tables as rosbag2 writes them, in pages ordered by (timestamp, id).

use super::{MAX_RECORD_BYTES, RawMessage, ReadOptions, TopicInfo};
use crate::{BagError, metadata};
use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use thiserror::Error;

/// sqlite rows fetched per query.
const SQLITE_PAGE: i64 = 64;

/// Why a sqlite3 storage file could not be read (one line each).
#[derive(Debug, Error)]
pub enum SqliteError {
    #[error("{0}")]
    Db(#[from] rusqlite::Error),
    #[error("more than {} topics", metadata::MAX_TOPICS)]
    TooManyTopics,
    #[error("message {id} names topic id {topic_id}, which is not in topics")]
    UnknownTopic { id: i64, topic_id: i64 },
    #[error("message {id}: {source}")]
    NotBlob {
        id: i64,
        source: rusqlite::types::FromSqlError,
    },
}

pub(super) struct SqliteFile {
    path: PathBuf,
    conn: rusqlite::Connection,
    topics: BTreeMap<i64, Arc<TopicInfo>>,
    page: VecDeque<RawMessage>,
    /// (timestamp, id) of the last row fetched.
    cursor: Option<(i64, i64)>,
    /// An oversized row met while filling the page: reported after the rows before it.
    pending: Option<BagError>,
    done: bool,
}

impl std::fmt::Debug for SqliteFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SqliteFile")
            .field("path", &self.path)
            .field("topics", &self.topics)
            .finish_non_exhaustive()
    }
}

impl SqliteFile {
    pub(super) fn open(path: &Path) -> Result<Self, BagError> {
        let err = |e: rusqlite::Error| BagError::Sqlite {
            path: path.to_path_buf(),
            error: SqliteError::Db(e),
        };
        let conn = rusqlite::Connection::open_with_flags(
            path,
            rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY | rusqlite::OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(err)?;
        let mut topics = BTreeMap::new();
        {
            let mut st = conn
                .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
                .map_err(err)?;
            let rows = st
                .query_map([], |r| {
                    Ok((
                        r.get::<_, i64>(0)?,
                        TopicInfo {
                            name: r.get(1)?,
                            type_name: r.get(2)?,
                            encoding: r.get(3)?,
                            schema: String::new(),
                        },
                    ))
                })
                .map_err(err)?;
            for row in rows {
                let (id, t) = row.map_err(err)?;
                if topics.len() >= metadata::MAX_TOPICS {
                    return Err(BagError::Sqlite {
                        path: path.to_path_buf(),
                        error: SqliteError::TooManyTopics,
                    });
                }
                topics.insert(id, Arc::new(t));
            }
        }
        Ok(Self {
            path: path.to_path_buf(),
            conn,
            topics,
            page: VecDeque::new(),
            cursor: None,
            pending: None,
            done: false,
        })
    }

    fn fill(&mut self, opts: &ReadOptions) -> Result<(), BagError> {
        let path = self.path.clone();
        let err = |e: rusqlite::Error| BagError::Sqlite {
            path: path.clone(),
            error: SqliteError::Db(e),
        };
        let (t0, id0) = self.cursor.unwrap_or((i64::MIN, i64::MIN));
        let mut st = self
            .conn
            .prepare_cached(
                // length() of a blob reads its size from the record header, not its pages:
                // an oversized row is counted and skipped without being read.
                "SELECT id, topic_id, timestamp, length(data), \
                 CASE WHEN length(data) <= ?4 THEN data END FROM messages \
                 WHERE timestamp > ?1 OR (timestamp = ?1 AND id > ?2) \
                 ORDER BY timestamp, id LIMIT ?3",
            )
            .map_err(err)?;
        let max = MAX_RECORD_BYTES as i64;
        let mut rows = st
            .query(rusqlite::params![t0, id0, SQLITE_PAGE, max])
            .map_err(err)?;
        let mut n = 0;
        let mut too_large = None;
        while let Some(r) = rows.next().map_err(err)? {
            n += 1;
            let id: i64 = r.get(0).map_err(err)?;
            let topic_id: i64 = r.get(1).map_err(err)?;
            let t: i64 = r.get(2).map_err(err)?;
            self.cursor = Some((t, id));
            let Some(topic) = self.topics.get(&topic_id) else {
                return Err(BagError::Sqlite {
                    path: path.clone(),
                    error: SqliteError::UnknownTopic { id, topic_id },
                });
            };
            if !opts.wants(&topic.name, t) {
                continue;
            }
            let len: Option<i64> = r.get(3).map_err(err)?;
            let len = len.unwrap_or(0);
            if len > max {
                too_large = Some(BagError::TooLarge {
                    path: path.clone(),
                    topic: Arc::clone(topic),
                    log_time: t,
                    len: len.unsigned_abs(),
                    max: MAX_RECORD_BYTES,
                });
                break;
            }
            let blob = r.get_ref(4).map_err(err)?;
            let data = blob.as_blob().map_err(|source| BagError::Sqlite {
                path: path.clone(),
                error: SqliteError::NotBlob { id, source },
            })?;
            self.page.push_back(RawMessage {
                topic: Arc::clone(topic),
                log_time: t,
                data: data.to_vec(),
            });
        }
        if n == 0 {
            self.done = true;
        }
        self.pending = too_large;
        Ok(())
    }

    pub(super) fn next(&mut self, opts: &ReadOptions) -> Result<Option<RawMessage>, BagError> {
        loop {
            if let Some(m) = self.page.pop_front() {
                return Ok(Some(m));
            }
            if let Some(e) = self.pending.take() {
                return Err(e);
            }
            if self.done {
                return Ok(None);
            }
            self.fill(opts)?;
        }
    }
}
