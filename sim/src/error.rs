//! Why a run could not be set up or carried out: the error every part of the
//! loop (the runner, its observers, the recorder, the remote environment) returns.

/// A run could not be set up or carried out.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The map could not be loaded.
    #[error(transparent)]
    Map(#[from] world::MapError),
    /// The route could not be read or planned.
    #[error(transparent)]
    Route(#[from] world::RouteError),
    /// The camera failed.
    #[error("camera: {0}")]
    Camera(String),
    /// The recorder failed.
    #[error(transparent)]
    Record(#[from] crate::recorder::RecordError),
    /// Something about the set-up is inconsistent.
    #[error("{0}")]
    Setup(String),
}
