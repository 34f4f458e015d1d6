pub mod case;
pub mod compare;
pub mod html;
pub mod inspect;
pub mod label_map;
pub mod pictures;
