pub mod case;
pub mod compare;
pub mod inspect;
