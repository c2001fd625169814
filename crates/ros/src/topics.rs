//! The topics of the stage graph's message kinds (launch/stage_graph.yaml): the topic, relative
//! so that namespaces and remaps apply, is the kind's name (`image` for frames, which the stage
//! node reads itself: raw or compressed, with drop counting); here each kind's QoS and its
//! conversion both ways. The generic stage node subscribes and publishes only through here.
//!
//! QoS: reliable (depth 10 out, 50 in) for every event; `background` latched (transient-local,
//! depth 1: a node started later still gets the sensor prior) and `tactile_latent`
//! transient-local, depth 10 (a predicted latent that went out at startup still reaches a policy
//! node started later), on both ends, since a transient-local subscription needs a
//! transient-local publisher. `depth` also publishes `points` (PointCloud2) beside it.

use crate::{convert, image};
use futures::StreamExt;
use r2r::QosProfile;
use r2r::unitac_msgs::msg as ros;
use thiserror::Error;
use unitac_core::{Msg, sensor_id_of};

/// A subscription to one kind, converted: each message, or why it is not one.
pub type Subscription = futures::stream::BoxStream<'static, Result<Msg, ReceiveError>>;

/// Publishes a message of the publisher's kind (other kinds are ignored).
pub type Publish = Box<dyn Fn(&Msg) -> r2r::Result<()>>;

/// A message received that does not make a valid core message.
#[derive(Debug, Error)]
pub enum ReceiveError {
    #[error("{kind}: {source}")]
    Convert {
        kind: &'static str,
        #[source]
        source: convert::ConvertError,
    },
    #[error("{kind}: {source}")]
    Image {
        kind: &'static str,
        #[source]
        source: unitac_bag::ImageError,
    },
}

/// Setting up a topic failed.
#[derive(Debug, Error)]
pub enum TopicError {
    #[error("no topic for message kind '{0}'")]
    UnknownKind(String),
    #[error("{kind}: {source}")]
    Ros {
        kind: String,
        #[source]
        source: r2r::Error,
    },
}

/// The topic of message kind `kind`.
pub fn topic(kind: &str) -> &str {
    if kind == "frame" { "image" } else { kind }
}

/// The QoS a kind is published with.
pub fn publisher_qos(kind: &str) -> QosProfile {
    match kind {
        "background" => QosProfile::default().keep_last(1).transient_local(),
        "tactile_latent" => QosProfile::default().keep_last(10).transient_local(),
        _ => QosProfile::default(),
    }
}

/// The QoS a kind is subscribed with.
pub fn subscription_qos(kind: &str) -> QosProfile {
    match kind {
        "background" => QosProfile::default().keep_last(1).transient_local(),
        "tactile_latent" => QosProfile::default().keep_last(10).transient_local(),
        "visual_observation" => QosProfile::default().keep_last(10),
        _ => QosProfile::default().keep_last(50),
    }
}

macro_rules! message_topics {
    (
        messages { $( $msg:ident [$to:ident, $from:ident] { $($fields:tt)* } )* }
        enums { $($e:tt)* }
    ) => {
        /// A publisher of one of the `unitac_msgs` kinds.
        fn message_publisher(node: &mut r2r::Node, kind: &str) -> r2r::Result<Option<Publish>> {
            $(
                if kind == stringify!($to) {
                    let p = node.create_publisher::<ros::$msg>(kind, publisher_qos(kind))?;
                    return Ok(Some(Box::new(move |m: &Msg| match m {
                        Msg::$msg(x) => p.publish(&convert::$to(x)),
                        _ => Ok(()),
                    })));
                }
            )*
            Ok(None)
        }

        /// A subscription to one of the `unitac_msgs` kinds.
        fn message_subscription(
            node: &mut r2r::Node,
            kind: &str,
        ) -> r2r::Result<Option<Subscription>> {
            $(
                if kind == stringify!($to) {
                    let s = node.subscribe::<ros::$msg>(kind, subscription_qos(kind))?;
                    return Ok(Some(Box::pin(s.map(|m| {
                        convert::$from(&m).map(Msg::$msg).map_err(|source| {
                            ReceiveError::Convert { kind: stringify!($to), source }
                        })
                    }))));
                }
            )*
            Ok(None)
        }
    };
}

unitac_core::for_each_message!(message_topics);

/// A publisher of `kind` on node `node`.
pub fn publisher(node: &mut r2r::Node, kind: &str) -> Result<Publish, TopicError> {
    let ros = |source| TopicError::Ros {
        kind: kind.to_string(),
        source,
    };
    let images = |node: &mut r2r::Node, kind: &str| {
        node.create_publisher::<r2r::sensor_msgs::msg::Image>(kind, publisher_qos(kind))
    };
    let p: Publish = match kind {
        "background" => {
            let p = images(node, kind).map_err(ros)?;
            Box::new(move |m| match m {
                Msg::Background(f) => p.publish(&image::from_frame(f)),
                _ => Ok(()),
            })
        }
        "contact_overlay" => {
            let p = images(node, kind).map_err(ros)?;
            Box::new(move |m| match m {
                Msg::ContactOverlay(f) => p.publish(&image::from_frame(f)),
                _ => Ok(()),
            })
        }
        "contact_clip" => {
            let p = node
                .create_publisher::<ros::ContactClip>(kind, publisher_qos(kind))
                .map_err(ros)?;
            Box::new(move |m| match m {
                Msg::ContactClip(c) => p.publish(&convert::contact_clip(c)),
                _ => Ok(()),
            })
        }
        "depth" => {
            let d = images(node, kind).map_err(ros)?;
            let pts = node
                .create_publisher::<r2r::sensor_msgs::msg::PointCloud2>(
                    "points",
                    publisher_qos("points"),
                )
                .map_err(ros)?;
            Box::new(move |m| match m {
                Msg::Depth(x) => {
                    d.publish(&image::depth(x))?;
                    pts.publish(&image::points(x))
                }
                _ => Ok(()),
            })
        }
        _ => message_publisher(node, kind)
            .map_err(ros)?
            .ok_or_else(|| TopicError::UnknownKind(kind.to_string()))?,
    };
    Ok(p)
}

/// A subscription to `kind` on node `node` (every kind but frames: the stage node reads images
/// itself).
pub fn subscription(node: &mut r2r::Node, kind: &str) -> Result<Subscription, TopicError> {
    let ros = |source| TopicError::Ros {
        kind: kind.to_string(),
        source,
    };
    let s: Subscription = match kind {
        "background" => {
            let s = node
                .subscribe::<r2r::sensor_msgs::msg::Image>(kind, subscription_qos(kind))
                .map_err(ros)?;
            Box::pin(s.map(|bg| {
                let id = sensor_id_of(None, &bg.header.frame_id, "sensor");
                image::to_frame(&bg, &id, 0)
                    .map(Msg::Background)
                    .map_err(|source| ReceiveError::Image {
                        kind: "background",
                        source,
                    })
            }))
        }
        "contact_clip" => {
            let s = node
                .subscribe::<ros::ContactClip>(kind, subscription_qos(kind))
                .map_err(ros)?;
            Box::pin(s.map(|c| {
                convert::contact_clip_from(&c)
                    .map(Msg::ContactClip)
                    .map_err(|source| ReceiveError::Convert {
                        kind: "contact_clip",
                        source,
                    })
            }))
        }
        _ => message_subscription(node, kind)
            .map_err(ros)?
            .ok_or_else(|| TopicError::UnknownKind(kind.to_string()))?,
    };
    Ok(s)
}
